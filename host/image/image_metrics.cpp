#include "image/image_metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace px {

ImageDifference compare_images(const ImageRGB& a, const ImageRGB& r, int row0, int row1) {
  if (a.width != r.width || a.height != r.height)
    throw ImageError("image is " + std::to_string(a.width) + "x" + std::to_string(a.height) + ", reference is " +
                     std::to_string(r.width) + "x" + std::to_string(r.height));
  if (row1 < 0) row1 = a.height;
  row0 = std::clamp(row0, 0, a.height);
  row1 = std::clamp(row1, row0, a.height);
  double se_clamped = 0.0, rel = 0.0;
  std::size_t n = 0;
  for (int y = row0; y < row1; ++y)
    for (int x = 0; x < a.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const std::size_t i = (static_cast<std::size_t>(y) * a.width + x) * 3 + c;
        const double va = a.rgb[i], vr = r.rgb[i];
        const double ca = std::clamp(va, 0.0, 1.0), cr = std::clamp(vr, 0.0, 1.0);
        se_clamped += (ca - cr) * (ca - cr);
        rel += (va - vr) * (va - vr) / (vr * vr + 0.01);
        ++n;
      }
  ImageDifference e;
  if (n == 0) return e;
  e.mse = se_clamped / n;
  e.rel_mse = rel / n;
  e.psnr_db = e.mse > 0.0 ? 10.0 * std::log10(1.0 / e.mse) : std::numeric_limits<double>::infinity();
  return e;
}

}  // namespace px
