// The error figures (host/image/image_metrics.*) against values worked out by hand on a 2x2 image
// with a light above 1, and the bit-exact comparison: identical images, one ulp in one channel of
// a pixel above 1, -0 vs +0, NaN payloads, and size mismatches.
#include "image/image_metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

namespace px {
namespace {

ImageRGB image(int w, int h, std::vector<float> rgb) {
  ImageRGB im;
  im.width = w;
  im.height = h;
  im.rgb = std::move(rgb);
  return im;
}

float from_bits(std::uint32_t b) {
  float v;
  std::memcpy(&v, &b, sizeof v);
  return v;
}

// 2x2, rows top to bottom, pixels (r, g, b). The reference's pixel (1, 0) is a light at 2.
ImageRGB reference_2x2() {
  return image(2, 2,
               {0.5f, 0.5f, 0.5f, /**/ 2.0f, 1.0f, 0.0f,  //
                0.25f, 0.25f, 0.25f, /**/ 0.0f, 0.0f, 0.0f});
}
// Differs in four values: (0,0).r by +0.25, (1,0).r by +1 (3 vs 2: both above 1, so the clamped
// values agree), (0,1).b by -0.25, (1,1).b by +0.5. Every value is exact in binary.
ImageRGB image_2x2() {
  return image(2, 2,
               {0.75f, 0.5f, 0.5f, /**/ 3.0f, 1.0f, 0.0f,  //
                0.25f, 0.25f, 0.0f, /**/ 0.0f, 0.0f, 0.5f});
}

TEST(ImageMetrics, FiguresOfA2x2ImageWithALightAboveOne) {
  const auto d = compare_images(image_2x2(), reference_2x2());
  // Squared errors: 0.0625 + 1 + 0.0625 + 0.25 = 1.375 over 12 values.
  EXPECT_DOUBLE_EQ(d.mse, 1.375 / 12);  // 0.114583...
  // A clamped mse would drop the light's 1 (clamp(3) - clamp(2) = 0): 0.375 / 12 = 0.03125.
  EXPECT_GT(std::fabs(d.mse - 0.375 / 12), 0.08);
  // (a - r)^2 / (r^2 + 0.01) per differing value; the others add 0.
  EXPECT_DOUBLE_EQ(d.rel_mse, (0.0625 / 0.26 + 1.0 / 4.01 + 0.0625 / 0.0725 + 0.25 / 0.01) / 12);  // 2.19598...
  // PSNR on clamped values: 10 log10(1 / 0.03125) = 10 log10(32) = 15.0515 dB.
  EXPECT_NEAR(d.psnr_db, 15.051499783199061, 1e-12);
}

TEST(ImageMetrics, RowRanges) {
  // Row 0 alone: squared errors 0.0625 + 1 over 6 values; clamped, 0.0625 over 6.
  const auto top = compare_images(image_2x2(), reference_2x2(), 0, 1);
  EXPECT_DOUBLE_EQ(top.mse, 1.0625 / 6);  // a clamped mse: 0.0625 / 6 = 0.0104167
  EXPECT_DOUBLE_EQ(top.rel_mse, (0.0625 / 0.26 + 1.0 / 4.01) / 6);
  EXPECT_NEAR(top.psnr_db, 19.822712330395685, 1e-12);  // 10 log10(96)
  // Row 1 to the end (row1 = -1): 0.0625 + 0.25 over 6, nothing above 1.
  const auto bottom = compare_images(image_2x2(), reference_2x2(), 1);
  EXPECT_DOUBLE_EQ(bottom.mse, 0.3125 / 6);
  EXPECT_DOUBLE_EQ(bottom.rel_mse, (0.0625 / 0.0725 + 0.25 / 0.01) / 6);
  EXPECT_NEAR(bottom.psnr_db, 12.833012287035498, 1e-12);  // 10 log10(19.2)
  // An empty range compares nothing.
  const auto none = compare_images(image_2x2(), reference_2x2(), 1, 1);
  EXPECT_EQ(none.mse, 0.0);
  EXPECT_EQ(none.rel_mse, 0.0);
}

TEST(ImageMetrics, OnlyTheLightDiffers) {
  // 1x1: 3 vs 2 in red. A display sees no difference (PSNR inf); mse and rel_mse do.
  const auto d = compare_images(image(1, 1, {3.0f, 0.5f, 0.5f}), image(1, 1, {2.0f, 0.5f, 0.5f}));
  EXPECT_DOUBLE_EQ(d.mse, 1.0 / 3);  // a clamped mse: 0
  EXPECT_DOUBLE_EQ(d.rel_mse, 1.0 / 4.01 / 3);
  EXPECT_EQ(d.psnr_db, std::numeric_limits<double>::infinity());
}

TEST(ImageMetrics, IdenticalImagesHaveNoError) {
  const auto d = compare_images(image_2x2(), image_2x2());
  EXPECT_EQ(d.mse, 0.0);
  EXPECT_EQ(d.rel_mse, 0.0);
  EXPECT_EQ(d.psnr_db, std::numeric_limits<double>::infinity());
}

TEST(ImageMetrics, SizeMismatchThrows) {
  const auto wide = image(2, 1, {0, 0, 0, 0, 0, 0});
  const auto tall = image(1, 2, {0, 0, 0, 0, 0, 0});
  EXPECT_THROW(compare_images(wide, tall), ImageError);
  EXPECT_THROW(compare_exact(wide, tall), ImageError);
  EXPECT_THROW(compare_exact(reference_2x2(), wide), ImageError);
  try {
    compare_exact(wide, tall);
  } catch (const ImageError& e) {
    EXPECT_STREQ(e.what(), "image is 2x1, reference is 1x2");
  }
}

TEST(CompareExact, IdenticalImages) {
  const auto d = compare_exact(image_2x2(), image_2x2());
  EXPECT_TRUE(d.identical());
  EXPECT_EQ(d.pixels, 4u);
  EXPECT_EQ(d.differing_pixels, 0u);
  EXPECT_EQ(d.differing_values, 0u);
  EXPECT_EQ(d.x, -1);
  EXPECT_EQ(d.max_abs_difference, 0.0);
}

TEST(CompareExact, OneUlpInAPixelAboveOne) {
  auto a = reference_2x2();
  a.rgb[3] = std::nextafter(2.0f, 3.0f);  // pixel (1, 0), red: 2 + 2^-22
  const auto d = compare_exact(a, reference_2x2());
  EXPECT_FALSE(d.identical());
  EXPECT_EQ(d.differing_pixels, 1u);
  EXPECT_EQ(d.differing_values, 1u);
  EXPECT_EQ(d.x, 1);
  EXPECT_EQ(d.y, 0);
  EXPECT_EQ(d.channel, 0);
  EXPECT_EQ(d.image_value, 2.0f + 0x1p-22f);
  EXPECT_EQ(d.reference_value, 2.0f);
  EXPECT_EQ(d.image_bits, 0x40000001u);
  EXPECT_EQ(d.reference_bits, 0x40000000u);
  EXPECT_EQ(d.max_abs_difference, 0x1p-22);  // 2.384185791015625e-07
  // What the clamped PSNR cannot see; mse does.
  const auto e = compare_images(a, reference_2x2());
  EXPECT_EQ(e.psnr_db, std::numeric_limits<double>::infinity());
  EXPECT_DOUBLE_EQ(e.mse, 0x1p-44 / 12);
}

TEST(CompareExact, CountsPixelsAndValuesAndFindsTheFirstAndLargest) {
  auto a = image_2x2();
  a.rgb[10] = 0.25f;  // (1,1).g too: that pixel now differs in two channels
  const auto d = compare_exact(a, reference_2x2());
  EXPECT_EQ(d.differing_pixels, 4u);
  EXPECT_EQ(d.differing_values, 5u);
  EXPECT_EQ(d.x, 0);
  EXPECT_EQ(d.y, 0);
  EXPECT_EQ(d.channel, 0);
  EXPECT_EQ(d.image_value, 0.75f);
  EXPECT_EQ(d.reference_value, 0.5f);
  EXPECT_EQ(d.max_abs_difference, 1.0);  // 3 vs 2
  EXPECT_EQ(d.nan_values, 0u);
}

TEST(CompareExact, SignedZerosDiffer) {
  auto a = reference_2x2();
  a.rgb[11] = -0.0f;  // pixel (1, 1), blue
  const auto d = compare_exact(a, reference_2x2());
  EXPECT_FALSE(d.identical());
  EXPECT_EQ(d.differing_values, 1u);
  EXPECT_EQ(d.x, 1);
  EXPECT_EQ(d.y, 1);
  EXPECT_EQ(d.channel, 2);
  EXPECT_EQ(d.image_bits, 0x80000000u);
  EXPECT_EQ(d.reference_bits, 0u);
  EXPECT_EQ(d.max_abs_difference, 0.0);                    // numerically equal
  EXPECT_EQ(compare_images(a, reference_2x2()).mse, 0.0);  // which is why mse 0 is not the check
}

TEST(CompareExact, NaNsCompareByPayload) {
  auto a = reference_2x2(), b = reference_2x2();
  a.rgb[4] = from_bits(0x7fc00000u);
  b.rgb[4] = from_bits(0x7fc00000u);
  EXPECT_TRUE(compare_exact(a, b).identical());  // the same NaN
  b.rgb[4] = from_bits(0x7fc00001u);
  const auto d = compare_exact(a, b);
  EXPECT_FALSE(d.identical());
  EXPECT_EQ(d.differing_values, 1u);
  EXPECT_EQ(d.channel, 1);
  EXPECT_EQ(d.nan_values, 1u);
  EXPECT_EQ(d.max_abs_difference, 0.0);
}

}  // namespace
}  // namespace px
