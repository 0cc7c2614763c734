// The writing of image files (the encoders in exr_writer.cpp and png_writer.cpp), the host-side
// preview encoding and the stereo layout; the reader is in image_codec_*.cpp.
#include "image/image_io.h"

#include "image/exr_writer.h"
#include "image/png_writer.h"
#include "io/atomic_file.h"

#include <algorithm>
#include <cmath>
#include <string_view>

namespace px {
namespace {

float linear_to_srgb(float c) {
  c = std::clamp(c, 0.0f, 1.0f);
  return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

// The encoder's bytes into `path`, atomically; every failure an ImageError naming the file.
template <typename Encode>
void write_encoded(const std::string& path, const Encode& encode) {
  std::string bytes;
  try {
    bytes = encode();
  } catch (const ImageError& e) {
    throw ImageError("cannot write " + path + ": " + e.what());
  }
  try {
    write_file_atomic(path, std::string_view(bytes));
  } catch (const WriteError& e) {
    throw ImageError(e.what());
  }
}

}  // namespace

void write_exr(const std::string& path, const ImageRGB& image) {
  write_encoded(path, [&] { return encode_exr(image); });
}

void write_png(const std::string& path, int width, int height, const std::vector<std::uint8_t>& rgba) {
  if (width <= 0 || height <= 0 || rgba.size() != static_cast<std::size_t>(width) * height * 4)
    throw ImageError("write_png " + path + ": buffer size does not match " + std::to_string(width) + "x" +
                     std::to_string(height));
  write_encoded(path, [&] { return encode_png(width, height, rgba.data()); });
}

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
