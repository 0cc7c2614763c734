// parallax view: a GLFW window showing both eyes side by side as the stereo pipeline finishes
// them, with a fly-through camera. Only the parallax executable compiles this (GLFW and OpenGL
// stay out of parallax_core); run_view itself is declared in app/commands.h.
//
// Threads: the render thread owns the OpenCL side (pipeline, control loop) and renders frame
// after frame; after each it hands the finished RGBA8 eyes over under a mutex (a vector swap).
// The main thread owns the window: it polls input, publishes the steered camera, and uploads
// the newest frame through a pixel buffer object. Neither waits for the other: the window never
// blocks the render queues, and a slow frame never freezes the window.
#pragma once

#include "scene/scene.h"

#include <glm/glm.hpp>

namespace px {

// The fly-through camera: position and view direction, turned about the scene camera's up.
class FlyCamera {
 public:
  // Starts at `from` (position, direction to its target, its up and field of view).
  explicit FlyCamera(const Camera& from);
  // Moves by `forward`, `right`, `up` scene units along the current view's axes.
  void move(float forward, float right, float up);
  // Turns by `yaw` radians about up (positive: to the left) and `pitch` radians about the
  // right axis (positive: upwards); the view stays short of straight up or down.
  void turn(float yaw, float pitch);
  Camera camera() const;

 private:
  glm::vec3 position_, direction_, up_;
  float vfov_deg_;
};

}  // namespace px
