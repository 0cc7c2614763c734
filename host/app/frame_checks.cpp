#include "app/frame_checks.h"

#include "render/stereo_camera.h"

#include <cmath>
#include <cstddef>
#include <cstdio>
#include <stdexcept>

namespace px {
namespace {

// Pixels of `image` with a NaN or infinite channel.
std::size_t count_nonfinite(const ImageRGB& image) {
  std::size_t bad = 0;
  for (std::size_t i = 0; i + 2 < image.rgb.size(); i += 3)
    bad += !(std::isfinite(image.rgb[i]) && std::isfinite(image.rgb[i + 1]) && std::isfinite(image.rgb[i + 2]));
  return bad;
}

}  // namespace

void require_finite(const std::array<ImageRGB, 2>& eyes, const std::string& what) {
  for (int e = 0; e < 2; ++e)
    if (const std::size_t bad = count_nonfinite(eyes[e]))
      throw std::runtime_error(what + ": " + std::to_string(bad) + " of " +
                               std::to_string(static_cast<std::size_t>(eyes[e].width) * eyes[e].height) +
                               " pixels of the " + (e == 0 ? "left" : "right") +
                               " eye are NaN or infinite (not written). The scene's coordinates or camera are "
                               "probably beyond what 32-bit floats resolve: scale or recentre it");
}

void check_camera(const Scene& scene, float time_s, const std::string& what) {
  const Camera c = evaluate_camera(scene, time_s);
  const glm::vec3 forward = c.target - c.position;
  const glm::vec3 side = glm::cross(forward, c.up);
  const float f2 = glm::dot(forward, forward), s2 = glm::dot(side, side);
  if (std::isfinite(f2) && f2 > 0.0f && std::isfinite(s2) && s2 > 0.0f) return;
  char when[64];
  std::snprintf(when, sizeof when, " (t = %.4g s)", double(time_s));
  throw std::runtime_error(what + when +
                           ": the camera path gives no view direction there (position meets target, "
                           "or the view is parallel to up); adjust the camera_path keys");
}

}  // namespace px
