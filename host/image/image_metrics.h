// Error of an image against a reference: the figures every speed number in this project is
// reported with, and the bit-exact comparison the "images identical" claims rest on.
#pragma once

#include "image/image_io.h"

#include <cstddef>
#include <cstdint>

namespace px {

// All three figures are means over the compared pixels and their 3 channels, with a the image
// and r the reference:
struct ImageDifference {
  double mse = 0.0;      // mean of (a - r)^2, unclamped radiance (a light at 5 counts as 5)
  double rel_mse = 0.0;  // mean of (a - r)^2 / (r^2 + 0.01), unclamped (robust to dark pixels)
  double psnr_db = 0.0;  // 10 log10(1 / mean of (clamp(a) - clamp(r))^2), clamp to [0, 1] as a
                         // display would (peak 1); +inf when the clamped values agree, which
                         // says nothing about pixels at or above 1: use compare_exact for that
};

// Compares rows [row0, row1) (all rows by default). Throws ImageError on a size mismatch.
ImageDifference compare_images(const ImageRGB& image, const ImageRGB& reference, int row0 = 0, int row1 = -1);

// Bit-for-bit comparison of the float pixel data: every channel of every pixel is compared by
// its bit pattern, so -0.0 vs +0.0 and NaNs with different payloads differ, and a NaN equals
// the same NaN.
struct ExactDifference {
  std::size_t pixels = 0;            // pixels compared (width * height)
  std::size_t differing_pixels = 0;  // pixels with at least one differing channel
  std::size_t differing_values = 0;  // differing channels, over all pixels
  // The first differing value in row-major order (y, then x, then channel); -1 when identical.
  int x = -1, y = -1, channel = -1;
  float image_value = 0.0f, reference_value = 0.0f;
  std::uint32_t image_bits = 0, reference_bits = 0;
  // The largest |a - r| over the differing values whose difference is a number (0 when every
  // difference is -0 vs +0 or involves a NaN); nan_values counts those involving a NaN.
  double max_abs_difference = 0.0;
  std::size_t nan_values = 0;

  bool identical() const { return differing_values == 0; }
};

// Throws ImageError on a size mismatch (same message as compare_images).
ExactDifference compare_exact(const ImageRGB& image, const ImageRGB& reference);

}  // namespace px
