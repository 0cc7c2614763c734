// Embree's own ray tracer over the same triangles, used two ways: as the speed reference the
// benchmark divides the kernel's rays/s by (rtcIntersect1 is the practical limit
// for single-ray traversal on a CPU), and as an independent second code path in tests.
#pragma once

#include "scene/scene.h"
#include "shared/types.h"

#include <embree3/rtcore.h>

#include <string>
#include <vector>

namespace px {

// The process-wide Embree device, created on first use and shared by the BVH builder and
// EmbreeReference: one device means one TBB arena and one error callback. The callback stores
// the message per thread; take_embree_error() returns it (and clears it), "" when there was none.
RTCDevice embree_device();
std::string take_embree_error();

class EmbreeReference {
 public:
  // Builds an RTCScene holding one triangle geometry; primitive i is triangles[i], so
  // Hit::prim indexes the same scene as BvhTriangle::prim. Throws std::runtime_error on an
  // Embree error. An empty vector gives a scene every ray misses.
  explicit EmbreeReference(const std::vector<SceneTriangle>& triangles);
  ~EmbreeReference();
  EmbreeReference(const EmbreeReference&) = delete;
  EmbreeReference& operator=(const EmbreeReference&) = delete;

  // Closest hit in [ray.tmin, ray.tmax] (rtcIntersect1); prim = PX_NO_HIT on a miss. u, v are
  // Embree's barycentrics of v1 and v2, the convention of px::Hit.
  Hit intersect(const Ray& ray) const;

  // Any hit in [ray.tmin, ray.tmax] (rtcOccluded1).
  bool occluded(const Ray& ray) const;

  // intersect() for every ray; hits is resized to rays.size(). threads > 1 splits the rays into
  // that many contiguous chunks on std::threads (Embree's queries are thread safe).
  void intersect_all(const std::vector<Ray>& rays, std::vector<Hit>& hits, int threads = 1) const;

 private:
  RTCScene scene_ = nullptr;
};

}  // namespace px
