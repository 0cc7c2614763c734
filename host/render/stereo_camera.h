// The stereo camera: two pinhole eyes with parallel view axes, separated by the
// interpupillary distance along the camera's right vector. Parallel axes keep epipolar lines
// horizontal, which is what lets reprojection gather along a single row (and so stay on the
// device that owns that row).
#pragma once

#include "scene/scene.h"
#include "shared/types.h"

#include <array>

namespace px {

enum class Eye : int { Left = 0, Right = 1 };

inline const char* eye_name(Eye e) { return e == Eye::Left ? "left" : "right"; }

// The centre camera at a time on the scene's path (the static camera when there is none).
Camera evaluate_camera(const Scene& scene, float time_s);

// Duration of the scene's camera path in seconds (0 for a static camera).
float camera_path_duration(const Scene& scene);

// One eye's camera constants for the kernels. `ipd_units` is the eye separation in scene
// units (Scene::ipd_units()); `jitter` the frame's position inside each pixel of the G-buffer
// ray and the first sample (pixel_jitter.h; the centre by default).
CameraParams make_eye_camera(const Camera& centre, Eye eye, float ipd_units, unsigned width, unsigned height,
                             std::array<float, 2> jitter = {0.5f, 0.5f});

}  // namespace px
