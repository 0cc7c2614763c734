// The host-side preview encoding and the stereo layout; the codec is in image_codec_*.cpp.
#include "image/image_io.h"

#include <algorithm>
#include <cmath>

namespace px {
namespace {

float linear_to_srgb(float c) {
  c = std::clamp(c, 0.0f, 1.0f);
  return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

}  // namespace

std::vector<std::uint8_t> to_srgb8(const ImageRGB& image, float exposure) {
  const std::size_t n = static_cast<std::size_t>(image.width) * image.height;
  std::vector<std::uint8_t> out(n * 4);
  for (std::size_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c)
      out[i * 4 + c] = static_cast<std::uint8_t>(std::lround(255.0f * linear_to_srgb(exposure * image.rgb[i * 3 + c])));
    out[i * 4 + 3] = 255;
  }
  return out;
}

std::vector<std::uint8_t> side_by_side(const std::vector<std::uint8_t>& left, const std::vector<std::uint8_t>& right,
                                       int width, int height) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(width) * 2 * height * 4);
  const std::size_t row = static_cast<std::size_t>(width) * 4;
  for (int y = 0; y < height; ++y) {
    std::copy_n(left.begin() + y * row, row, out.begin() + y * 2 * row);
    std::copy_n(right.begin() + y * row, row, out.begin() + y * 2 * row + row);
  }
  return out;
}

}  // namespace px
