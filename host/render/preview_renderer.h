// Renders the preview (primary-hit shading) of both eyes, each device taking one contiguous
// strip of rows of each eye. A geometry and framing check, and the first thing the demo shows.
#pragma once

#include "cl/device_set.h"
#include "image/image_io.h"
#include "render/device_scene.h"
#include "render/stereo_camera.h"

#include <array>

namespace px {

class PreviewRenderer {
 public:
  PreviewRenderer(DeviceSet& devices, const DeviceScene& scene) : devices_(devices), scene_(scene) {}

  // Both eyes of the scene at `time_s`.
  std::array<ImageRGB, 2> render(const Scene& scene, float time_s, unsigned width, unsigned height);

 private:
  DeviceSet& devices_;
  const DeviceScene& scene_;
};

}  // namespace px
