// Independent reference for the trace kernels: every triangle tested against every ray, in
// double precision, with the Möller–Trumbore algorithm (a different algorithm from the
// kernels' watertight shear test, so the two share no code and no systematic error).
#pragma once

#include "scene/scene.h"
#include "shared/types.h"

#include <glm/glm.hpp>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace px::test {

struct BruteHit {
  double t = std::numeric_limits<double>::infinity();
  std::uint32_t prim = PX_NO_HIT;
  double u = 0, v = 0;
  // Smallest barycentric of the hit: near zero the ray grazes an edge, where two triangles
  // may legitimately both claim it.
  double edge_distance = 1;
};

inline BruteHit brute_force_closest(const std::vector<SceneTriangle>& tris, const Ray& r) {
  const glm::dvec3 o(r.org[0], r.org[1], r.org[2]);
  const glm::dvec3 d(r.dir[0], r.dir[1], r.dir[2]);
  BruteHit best;
  best.t = r.tmax;
  for (std::size_t i = 0; i < tris.size(); ++i) {
    const glm::dvec3 p0(tris[i].p[0]), p1(tris[i].p[1]), p2(tris[i].p[2]);
    const glm::dvec3 e1 = p1 - p0, e2 = p2 - p0;
    const glm::dvec3 pv = glm::cross(d, e2);
    const double det = glm::dot(e1, pv);
    if (det == 0.0) continue;
    const double inv = 1.0 / det;
    const glm::dvec3 tv = o - p0;
    const double u = glm::dot(tv, pv) * inv;
    if (u < 0.0 || u > 1.0) continue;
    const glm::dvec3 qv = glm::cross(tv, e1);
    const double v = glm::dot(d, qv) * inv;
    if (v < 0.0 || u + v > 1.0) continue;
    const double t = glm::dot(e2, qv) * inv;
    if (t <= r.tmin || t >= best.t) continue;  // (tmin, tmax), as the kernels
    best.t = t;
    best.prim = static_cast<std::uint32_t>(i);
    best.u = u;
    best.v = v;
    best.edge_distance = std::min({u, v, 1.0 - u - v});
  }
  return best;
}

// A direction uniform on the unit sphere (a normalised Gaussian vector).
inline glm::vec3 random_unit(std::mt19937& rng) {
  std::normal_distribution<float> n;
  glm::vec3 v;
  do v = glm::vec3(n(rng), n(rng), n(rng));
  while (glm::dot(v, v) < 1e-6f);
  return glm::normalize(v);
}

inline Ray make_ray(glm::vec3 o, glm::vec3 d, float tmin = 0.0f, float tmax = std::numeric_limits<float>::infinity()) {
  Ray r{};
  for (int i = 0; i < 3; ++i) {
    r.org[i] = o[i];
    r.dir[i] = d[i];
  }
  r.tmin = tmin;
  r.tmax = tmax;
  return r;
}

}  // namespace px::test
