// The live viewer's fly-through camera (parallax view) without a window: moves go along the
// view's axes, turns keep the camera a valid view (never parallel to up, so never a NaN frame).
#include "render/fly_camera.h"

#include <gtest/gtest.h>

#include <cmath>

namespace px {
namespace {

Camera looking_down_z() {
  Camera c;
  c.position = {0.0f, 1.0f, 5.0f};
  c.target = {0.0f, 1.0f, 0.0f};
  c.up = {0.0f, 1.0f, 0.0f};
  c.vfov_deg = 40.0f;
  return c;
}

void expect_near(const glm::vec3& a, const glm::vec3& b, float eps = 1e-5f) {
  EXPECT_NEAR(a.x, b.x, eps);
  EXPECT_NEAR(a.y, b.y, eps);
  EXPECT_NEAR(a.z, b.z, eps);
}

glm::vec3 direction(const Camera& c) { return glm::normalize(c.target - c.position); }

TEST(FlyCamera, StartsWhereTheSceneCameraIs) {
  const Camera c = FlyCamera(looking_down_z()).camera();
  expect_near(c.position, {0.0f, 1.0f, 5.0f});
  expect_near(direction(c), {0.0f, 0.0f, -1.0f});
  expect_near(c.up, {0.0f, 1.0f, 0.0f});
  EXPECT_EQ(c.vfov_deg, 40.0f);
}

TEST(FlyCamera, MovesAlongTheViewAxes) {
  FlyCamera fly(looking_down_z());
  fly.move(2.0f, 0.0f, 0.0f);  // forward: -z
  expect_near(fly.camera().position, {0.0f, 1.0f, 3.0f});
  fly.move(0.0f, 1.0f, 0.0f);  // right of a -z view: +x
  expect_near(fly.camera().position, {1.0f, 1.0f, 3.0f});
  fly.move(0.0f, 0.0f, -0.5f);  // down
  expect_near(fly.camera().position, {1.0f, 0.5f, 3.0f});
  expect_near(direction(fly.camera()), {0.0f, 0.0f, -1.0f});
}

TEST(FlyCamera, YawTurnsLeftAboutUp) {
  FlyCamera fly(looking_down_z());
  fly.turn(static_cast<float>(M_PI / 2), 0.0f);  // a quarter turn left: from -z to -x
  expect_near(direction(fly.camera()), {-1.0f, 0.0f, 0.0f});
  fly.move(1.0f, 0.0f, 0.0f);
  expect_near(fly.camera().position, {-1.0f, 1.0f, 5.0f});
}

TEST(FlyCamera, PitchStopsShortOfStraightUpOrDown) {
  FlyCamera fly(looking_down_z());
  fly.turn(0.0f, 0.3f);
  EXPECT_GT(direction(fly.camera()).y, 0.2f);  // looking up
  for (int i = 0; i < 50; ++i) fly.turn(0.0f, 0.2f);
  for (const float sign : {1.0f, -1.0f}) {
    for (int i = 0; i < 50; ++i) fly.turn(0.0f, sign * 0.2f);
    const Camera c = fly.camera();
    const glm::vec3 d = direction(c);
    EXPECT_LT(std::abs(d.y), 0.9999f);
    EXPECT_GT(glm::length(glm::cross(d, c.up)), 1e-3f);  // a right axis exists: a valid view
    EXPECT_TRUE(std::isfinite(d.x) && std::isfinite(d.y) && std::isfinite(d.z));
  }
}

TEST(FlyCamera, DegenerateStartStillGivesAView) {
  Camera c = looking_down_z();
  c.target = c.position;  // no direction
  const Camera out = FlyCamera(c).camera();
  const glm::vec3 d = out.target - out.position;
  EXPECT_GT(glm::length(d), 0.0f);
}

}  // namespace
}  // namespace px
