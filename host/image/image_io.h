// Image files: linear float EXR (radiance, for references and error figures) and 8-bit PNG
// (what a person looks at). Thin wrappers over OpenImageIO that throw ImageError with the path
// on failure.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace px {

struct ImageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Linear RGB float image, rows top to bottom.
struct ImageRGB {
  int width = 0;
  int height = 0;
  std::vector<float> rgb;  // width * height * 3
};

void write_exr(const std::string& path, const ImageRGB& image);
ImageRGB read_image_rgb(const std::string& path);  // any format OIIO reads; alpha dropped

// 8-bit RGBA, rows top to bottom.
void write_png(const std::string& path, int width, int height, const std::vector<std::uint8_t>& rgba);

// Linear -> sRGB-encoded 8 bit with exposure scale and clamp (a preview tonemap for host-side
// images; the pipeline's tonemap stage runs on the devices).
std::vector<std::uint8_t> to_srgb8(const ImageRGB& image, float exposure = 1.0f);

// Places `left` and `right` side by side (same size) — the stereo PNG layout.
std::vector<std::uint8_t> side_by_side(const std::vector<std::uint8_t>& left,
                                       const std::vector<std::uint8_t>& right, int width, int height);

}  // namespace px
