#include "image/image_metrics.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace px {

namespace {

void require_same_size(const ImageRGB& a, const ImageRGB& r) {
  if (a.width != r.width || a.height != r.height)
    throw ImageError("image is " + std::to_string(a.width) + "x" + std::to_string(a.height) + ", reference is " +
                     std::to_string(r.width) + "x" + std::to_string(r.height));
}

std::uint32_t bits_of(float v) {
  std::uint32_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

}  // namespace

ImageDifference compare_images(const ImageRGB& a, const ImageRGB& r, int row0, int row1) {
  require_same_size(a, r);
  if (row1 < 0) row1 = a.height;
  row0 = std::clamp(row0, 0, a.height);
  row1 = std::clamp(row1, row0, a.height);
  double se = 0.0, se_clamped = 0.0, rel = 0.0;
  std::size_t n = 0;
  for (int y = row0; y < row1; ++y)
    for (int x = 0; x < a.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const std::size_t i = (static_cast<std::size_t>(y) * a.width + x) * 3 + c;
        const double va = a.rgb[i], vr = r.rgb[i];
        const double ca = std::clamp(va, 0.0, 1.0), cr = std::clamp(vr, 0.0, 1.0);
        se += (va - vr) * (va - vr);
        se_clamped += (ca - cr) * (ca - cr);
        rel += (va - vr) * (va - vr) / (vr * vr + 0.01);
        ++n;
      }
  ImageDifference e;
  if (n == 0) return e;
  e.mse = se / n;
  e.rel_mse = rel / n;
  const double mse_clamped = se_clamped / n;
  e.psnr_db = mse_clamped > 0.0 ? 10.0 * std::log10(1.0 / mse_clamped) : std::numeric_limits<double>::infinity();
  return e;
}

ExactDifference compare_exact(const ImageRGB& a, const ImageRGB& r) {
  require_same_size(a, r);
  ExactDifference d;
  d.pixels = static_cast<std::size_t>(a.width) * a.height;
  for (std::size_t p = 0; p < d.pixels; ++p) {
    bool pixel_differs = false;
    for (int c = 0; c < 3; ++c) {
      const std::size_t i = p * 3 + c;
      const float va = a.rgb[i], vr = r.rgb[i];
      const std::uint32_t ba = bits_of(va), br = bits_of(vr);
      if (ba == br) continue;
      pixel_differs = true;
      if (d.differing_values++ == 0) {
        d.x = static_cast<int>(p % a.width);
        d.y = static_cast<int>(p / a.width);
        d.channel = c;
        d.image_value = va;
        d.reference_value = vr;
        d.image_bits = ba;
        d.reference_bits = br;
      }
      const double diff = std::fabs(static_cast<double>(va) - static_cast<double>(vr));
      if (std::isnan(diff))
        ++d.nan_values;
      else
        d.max_abs_difference = std::max(d.max_abs_difference, diff);
    }
    if (pixel_differs) ++d.differing_pixels;
  }
  return d;
}

}  // namespace px
