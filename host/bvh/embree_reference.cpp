#include "bvh/embree_reference.h"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <thread>

namespace px {

namespace {

// Embree reports errors through a callback on the thread that made the failing API call, so a
// per-thread slot keeps concurrent callers (a test building two BVHs at once) apart.
thread_local std::string t_embree_error;

void on_embree_error(void*, RTCError code, const char* message) {
  if (code == RTC_ERROR_NONE) return;
  if (!t_embree_error.empty()) t_embree_error += "; ";
  t_embree_error += message ? message : "unknown Embree error";
  t_embree_error += " (RTCError " + std::to_string(static_cast<int>(code)) + ")";
}

struct DeviceHolder {
  RTCDevice device = nullptr;
  DeviceHolder() {
    device = rtcNewDevice(nullptr);
    if (!device)
      throw std::runtime_error("Embree: rtcNewDevice failed (RTCError " +
                               std::to_string(static_cast<int>(rtcGetDeviceError(nullptr))) + ")");
    rtcSetDeviceErrorFunction(device, on_embree_error, nullptr);
  }
  ~DeviceHolder() {
    if (device) rtcReleaseDevice(device);
  }
};

// Throws with the message the callback stored (or the device's error code) if the last calls
// on this thread failed.
void throw_if_embree_failed(const char* what) {
  std::string message = take_embree_error();
  const RTCError code = rtcGetDeviceError(embree_device());
  if (message.empty() && code != RTC_ERROR_NONE) message = "RTCError " + std::to_string(static_cast<int>(code));
  if (!message.empty()) throw std::runtime_error(std::string("Embree: ") + what + ": " + message);
}

RTCRay to_rtc_ray(const Ray& ray) {
  RTCRay r;
  r.org_x = ray.org[0];
  r.org_y = ray.org[1];
  r.org_z = ray.org[2];
  r.tnear = ray.tmin;
  r.dir_x = ray.dir[0];
  r.dir_y = ray.dir[1];
  r.dir_z = ray.dir[2];
  r.time = 0.0f;
  r.tfar = ray.tmax;
  r.mask = 0xffffffffu;
  r.id = 0;
  r.flags = 0;
  return r;
}

}  // namespace

RTCDevice embree_device() {
  // Function-local static: created once, thread-safely, on first use.
  static DeviceHolder holder;
  return holder.device;
}

std::string take_embree_error() {
  std::string message;
  message.swap(t_embree_error);
  return message;
}

EmbreeReference::EmbreeReference(const std::vector<SceneTriangle>& triangles) {
  RTCDevice device = embree_device();
  take_embree_error();
  rtcGetDeviceError(device);  // clears a stale code left by an earlier call on this thread

  scene_ = rtcNewScene(device);
  // The reference should be the fastest Embree can trace, so spend build time on quality.
  rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
  if (!triangles.empty()) {
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    const std::size_t n = triangles.size();
    // Unshared vertices: three per triangle, so primID i is triangles[i] without an index
    // remap. rtcSetNewGeometryBuffer pads the allocation as Embree's SIMD loads require.
    auto* vertices = static_cast<float*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 3 * n));
    auto* indices = static_cast<unsigned*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), n));
    if (!vertices || !indices) {
      rtcReleaseGeometry(geometry);
      rtcReleaseScene(scene_);
      scene_ = nullptr;
      throw_if_embree_failed("allocating geometry buffers");
      throw std::runtime_error("Embree: allocating geometry buffers failed");
    }
    for (std::size_t i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) {
        vertices[9 * i + 3 * k + 0] = triangles[i].p[k].x;
        vertices[9 * i + 3 * k + 1] = triangles[i].p[k].y;
        vertices[9 * i + 3 * k + 2] = triangles[i].p[k].z;
        indices[3 * i + k] = static_cast<unsigned>(3 * i + k);
      }
    }
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(scene_, geometry);
    rtcReleaseGeometry(geometry);  // the scene holds its own reference
  }
  rtcCommitScene(scene_);
  try {
    throw_if_embree_failed("building the reference scene");
  } catch (...) {
    rtcReleaseScene(scene_);
    scene_ = nullptr;
    throw;
  }
}

EmbreeReference::~EmbreeReference() {
  if (scene_) rtcReleaseScene(scene_);
}

Hit EmbreeReference::intersect(const Ray& ray) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rayhit;
  rayhit.ray = to_rtc_ray(ray);
  rayhit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rayhit.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rayhit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene_, &context, &rayhit);

  Hit hit;
  hit.inst = PX_NO_INSTANCE;
  if (rayhit.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
    hit.t = ray.tmax;
    hit.u = hit.v = 0.0f;
    hit.prim = PX_NO_HIT;
  } else {
    hit.t = rayhit.ray.tfar;
    hit.u = rayhit.hit.u;
    hit.v = rayhit.hit.v;
    hit.prim = rayhit.hit.primID;
  }
  return hit;
}

bool EmbreeReference::occluded(const Ray& ray) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay r = to_rtc_ray(ray);
  rtcOccluded1(scene_, &context, &r);
  // Embree marks an occluded ray by setting tfar to -inf.
  return r.tfar == -std::numeric_limits<float>::infinity();
}

void EmbreeReference::intersect_all(const std::vector<Ray>& rays, std::vector<Hit>& hits, int threads) const {
  hits.resize(rays.size());
  const std::size_t n = rays.size();
  auto trace_range = [&](std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) hits[i] = intersect(rays[i]);
  };
  const std::size_t chunks = std::clamp<std::size_t>(threads > 0 ? threads : 1, 1, std::max<std::size_t>(n, 1));
  if (chunks == 1) {
    trace_range(0, n);
    return;
  }
  // Contiguous chunks keep neighbouring (coherent) rays on one thread, as a tile would.
  std::vector<std::thread> workers;
  workers.reserve(chunks - 1);
  for (std::size_t c = 1; c < chunks; ++c) workers.emplace_back(trace_range, n * c / chunks, n * (c + 1) / chunks);
  trace_range(0, n / chunks);
  for (auto& worker : workers) worker.join();
}

}  // namespace px
