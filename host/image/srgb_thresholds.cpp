#include "image/srgb_thresholds.h"

#include <cmath>

namespace px {
namespace {

double srgb_encode(double c) { return c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055; }

double srgb_decode(double v) { return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4); }

bool reaches(float c, int k) { return std::lround(255.0 * srgb_encode(static_cast<double>(c))) >= k; }

}  // namespace

std::array<float, 256> srgb8_thresholds() {
  std::array<float, 256> t{};
  for (int k = 1; k < 256; ++k) {
    // The exact boundary is where 255 * srgb(c) = k - 0.5; the decoded value lands within a few
    // ulps of the first float that rounds up, so step to it from there.
    float c = static_cast<float>(srgb_decode((k - 0.5) / 255.0));
    while (c > 0.0f && reaches(std::nextafter(c, 0.0f), k)) c = std::nextafter(c, 0.0f);
    while (!reaches(c, k)) c = std::nextafter(c, 2.0f);
    t[static_cast<std::size_t>(k)] = c;
  }
  return t;
}

}  // namespace px
