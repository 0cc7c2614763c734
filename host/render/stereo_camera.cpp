#include "render/stereo_camera.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace px {

Camera evaluate_camera(const Scene& scene, float time_s) {
  Camera cam = scene.camera;
  const auto& path = scene.camera_path;
  if (path.empty()) return cam;
  if (time_s <= path.front().time) {
    cam.position = path.front().position;
    cam.target = path.front().target;
    return cam;
  }
  if (time_s >= path.back().time) {
    cam.position = path.back().position;
    cam.target = path.back().target;
    return cam;
  }
  auto next =
      std::upper_bound(path.begin(), path.end(), time_s, [](float t, const CameraKey& k) { return t < k.time; });
  auto prev = next - 1;
  const float span = next->time - prev->time;
  const float a = span > 0.0f ? (time_s - prev->time) / span : 0.0f;
  cam.position = glm::mix(prev->position, next->position, a);
  cam.target = glm::mix(prev->target, next->target, a);
  return cam;
}

float camera_path_duration(const Scene& scene) {
  return scene.camera_path.empty() ? 0.0f : scene.camera_path.back().time;
}

CameraParams make_eye_camera(const Camera& centre, Eye eye, float ipd_units, unsigned width, unsigned height,
                             std::array<float, 2> jitter) {
  if (!(jitter[0] >= 0.0f && jitter[0] < 1.0f && jitter[1] >= 0.0f && jitter[1] < 1.0f))
    throw std::invalid_argument("make_eye_camera: the jitter must lie in [0, 1)^2");
  const glm::vec3 forward = glm::normalize(centre.target - centre.position);
  // Right-handed: right = forward x up. Re-orthogonalise up so the basis is exact.
  const glm::vec3 right = glm::normalize(glm::cross(forward, centre.up));
  const glm::vec3 up = glm::cross(right, forward);
  const float half = 0.5f * ipd_units * (eye == Eye::Left ? -1.0f : 1.0f);
  const glm::vec3 origin = centre.position + half * right;

  CameraParams p{};
  for (int i = 0; i < 3; ++i) {
    p.origin[i] = origin[i];
    p.right[i] = right[i];
    p.up[i] = up[i];
    p.forward[i] = forward[i];
  }
  p.tan_half_fov_y = std::tan(0.5f * glm::radians(centre.vfov_deg));
  p.aspect = static_cast<float>(width) / static_cast<float>(height);
  p.width = width;
  p.height = height;
  p.jitter[0] = jitter[0];
  p.jitter[1] = jitter[1];
  return p;
}

}  // namespace px
