// The live viewer's fly-through camera (parallax view): a position and view direction, moved
// along the view's own axes and turned about the scene camera's up. No window code here, so
// it is unit-tested with the rest of the core library.
#pragma once

#include "scene/scene.h"

#include <glm/glm.hpp>

namespace px {

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
