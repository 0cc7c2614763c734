#include "render/fly_camera.h"

#include <glm/gtc/quaternion.hpp>

#include <cmath>

namespace px {

FlyCamera::FlyCamera(const Camera& from)
    : position_(from.position), up_(glm::normalize(from.up)), vfov_deg_(from.vfov_deg) {
  const glm::vec3 d = from.target - from.position;
  direction_ = glm::dot(d, d) > 0.0f ? glm::normalize(d) : glm::vec3(0.0f, 0.0f, -1.0f);
}

void FlyCamera::move(float forward, float right, float up) {
  const glm::vec3 side = glm::cross(direction_, up_);
  const glm::vec3 r = glm::dot(side, side) > 0.0f ? glm::normalize(side) : glm::vec3(1.0f, 0.0f, 0.0f);
  position_ += forward * direction_ + right * r + up * up_;
}

void FlyCamera::turn(float yaw, float pitch) {
  direction_ = glm::normalize(glm::angleAxis(yaw, up_) * direction_);
  const glm::vec3 side = glm::cross(direction_, up_);
  if (glm::dot(side, side) <= 0.0f) return;
  const glm::vec3 pitched = glm::normalize(glm::angleAxis(pitch, glm::normalize(side)) * direction_);
  // Stay within ~85 degrees of the horizon: at the pole the right axis is undefined.
  if (std::abs(glm::dot(pitched, up_)) < 0.996f) direction_ = pitched;
}

Camera FlyCamera::camera() const {
  Camera c;
  c.position = position_;
  c.target = position_ + direction_;
  c.up = up_;
  c.vfov_deg = vfov_deg_;
  return c;
}

}  // namespace px
