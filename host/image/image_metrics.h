// Error of an image against a reference: the figures every speed number in this project is
// reported with.
#pragma once

#include "image/image_io.h"

namespace px {

struct ImageDifference {
  double mse = 0.0;      // mean over pixels and channels of (a - r)^2
  double rel_mse = 0.0;  // mean of (a - r)^2 / (r^2 + 0.01), channel-wise (robust to dark pixels)
  double psnr_db = 0.0;  // 10 log10(peak^2 / mse) with peak = 1 (clamped radiance)
};

// Compares rows [row0, row1) (all rows by default). Radiance is clamped to [0, 1] for PSNR, as
// a display would; rel_mse uses the unclamped values. Throws ImageError on a size mismatch.
ImageDifference compare_images(const ImageRGB& image, const ImageRGB& reference, int row0 = 0, int row1 = -1);

}  // namespace px
