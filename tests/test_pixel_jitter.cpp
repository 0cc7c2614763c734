// The per-frame sample position inside each pixel (render/pixel_jitter.h): the radical inverse
// against digits mirrored by hand, and the property temporal anti-aliasing relies on: any
// 2^a 3^b consecutive frames put one point in every cell of a 2^a x 3^b grid over the pixel.
#include "render/pixel_jitter.h"
#include "render/stereo_camera.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <vector>

using namespace px;

TEST(PixelJitter, RadicalInverseMirrorsTheDigits) {
  // base 2: 1 = 1b -> 0.1b, 2 = 10b -> 0.01b, 3 = 11b -> 0.11b, 6 = 110b -> 0.011b
  EXPECT_EQ(radical_inverse(2, 0), 0.0f);
  EXPECT_EQ(radical_inverse(2, 1), 0.5f);
  EXPECT_EQ(radical_inverse(2, 2), 0.25f);
  EXPECT_EQ(radical_inverse(2, 3), 0.75f);
  EXPECT_EQ(radical_inverse(2, 6), 0.375f);
  // base 3: 1 -> 1/3, 2 -> 2/3, 3 = 10_3 -> 0.01_3 = 1/9, 5 = 12_3 -> 0.21_3 = 7/9
  EXPECT_FLOAT_EQ(radical_inverse(3, 1), 1.0f / 3.0f);
  EXPECT_FLOAT_EQ(radical_inverse(3, 2), 2.0f / 3.0f);
  EXPECT_FLOAT_EQ(radical_inverse(3, 3), 1.0f / 9.0f);
  EXPECT_FLOAT_EQ(radical_inverse(3, 5), 7.0f / 9.0f);
  // The largest index stays below 1.
  EXPECT_LT(radical_inverse(2, 0xffffffffu), 1.0f);
  EXPECT_LT(radical_inverse(3, 0xffffffffu), 1.0f);
  EXPECT_THROW(radical_inverse(1, 3), std::invalid_argument);
}

TEST(PixelJitter, CentreModeIsThePixelCentreEveryFrame) {
  for (unsigned f : {0u, 1u, 7u, 1000u}) {
    const auto j = pixel_jitter(PixelJitter::Centre, f);
    EXPECT_EQ(j[0], 0.5f);
    EXPECT_EQ(j[1], 0.5f);
  }
}

TEST(PixelJitter, ConsecutiveFramesCoverThePixelEvenly) {
  // 72 = 8 x 9 consecutive frames, from frame 0 and from an arbitrary frame: each of the 8 x 9
  // cells of the pixel holds exactly one frame's point.
  for (unsigned first : {0u, 1u, 1000u, 123457u}) {
    std::vector<int> hits(72, 0);
    double mx = 0, my = 0;
    for (unsigned f = first; f < first + 72; ++f) {
      const auto j = pixel_jitter(PixelJitter::Halton, f);
      ASSERT_GE(j[0], 0.0f);
      ASSERT_LT(j[0], 1.0f);
      ASSERT_GE(j[1], 0.0f);
      ASSERT_LT(j[1], 1.0f);
      ++hits[static_cast<int>(j[1] * 9) * 8 + static_cast<int>(j[0] * 8)];
      mx += j[0];
      my += j[1];
    }
    for (int c = 0; c < 72; ++c) EXPECT_EQ(hits[c], 1) << "cell " << c << " from frame " << first;
    // The points' mean is the pixel centre within half a cell.
    EXPECT_NEAR(mx / 72, 0.5, 1.0 / 16);
    EXPECT_NEAR(my / 72, 0.5, 1.0 / 18);
  }
}

TEST(PixelJitter, TheCameraCarriesTheJitterAndRefusesPointsOutsideThePixel) {
  Camera c;
  c.position = {0, 0, 0};
  c.target = {0, 0, 1};
  const CameraParams p = make_eye_camera(c, Eye::Left, 0.0f, 16, 9, {0.25f, 0.75f});
  EXPECT_EQ(p.jitter[0], 0.25f);
  EXPECT_EQ(p.jitter[1], 0.75f);
  const CameraParams centred = make_eye_camera(c, Eye::Left, 0.0f, 16, 9);
  EXPECT_EQ(centred.jitter[0], 0.5f);
  EXPECT_EQ(centred.jitter[1], 0.5f);
  EXPECT_THROW(make_eye_camera(c, Eye::Left, 0.0f, 16, 9, {1.0f, 0.5f}), std::invalid_argument);
  EXPECT_THROW(make_eye_camera(c, Eye::Left, 0.0f, 16, 9, {0.5f, -0.1f}), std::invalid_argument);
}
