#include "image/image_io.h"

#include "io/atomic_file.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>

namespace px {
namespace {

// Encodes into memory (an OIIO IOProxy) and hands the bytes to write_file_atomic: OIIO's own
// file output does not report every failed write or close (a full disk gave 0-byte files and
// success), and a file written in place is truncated under its final name if the run stops.
void write_image(const std::string& path, int width, int height, int channels, OIIO::TypeDesc type,
                 const void* pixels) {
  std::vector<unsigned char> encoded;
  OIIO::Filesystem::IOVecOutput proxy(encoded);
  auto out = OIIO::ImageOutput::create(path, &proxy);
  if (!out) throw ImageError("cannot write " + path + ": " + OIIO::geterror());
  if (!out->supports("ioproxy"))
    throw ImageError("cannot write " + path + ": the " + out->format_name() +
                     " writer of this OpenImageIO cannot encode into memory");
  OIIO::ImageSpec spec(width, height, channels, type);
  if (!out->open(path, spec)) throw ImageError("cannot encode " + path + ": " + out->geterror());
  if (!out->write_image(type, pixels)) throw ImageError("cannot encode " + path + ": " + out->geterror());
  if (!out->close()) throw ImageError("cannot encode " + path + ": " + out->geterror());
  out.reset();
  try {
    write_file_atomic(path, std::string_view(reinterpret_cast<const char*>(encoded.data()), encoded.size()));
  } catch (const WriteError& e) {
    throw ImageError(e.what());
  }
}

float linear_to_srgb(float c) {
  c = std::clamp(c, 0.0f, 1.0f);
  return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

}  // namespace

void write_exr(const std::string& path, const ImageRGB& image) {
  write_image(path, image.width, image.height, 3, OIIO::TypeDesc::FLOAT, image.rgb.data());
}

ImageRGB read_image_rgb(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw ImageError("cannot read " + path + ": " + OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.nchannels < 1) throw ImageError(path + ": image has no channels");
  std::vector<float> all(static_cast<std::size_t>(spec.width) * spec.height * spec.nchannels);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, all.data()))
    throw ImageError("cannot read " + path + ": " + in->geterror());
  ImageRGB img;
  img.width = spec.width;
  img.height = spec.height;
  img.rgb.resize(static_cast<std::size_t>(img.width) * img.height * 3);
  for (std::size_t i = 0; i < static_cast<std::size_t>(img.width) * img.height; ++i)
    for (int c = 0; c < 3; ++c)
      img.rgb[i * 3 + c] = all[i * spec.nchannels + std::min(c, spec.nchannels - 1)];
  return img;
}

void write_png(const std::string& path, int width, int height, const std::vector<std::uint8_t>& rgba) {
  if (rgba.size() != static_cast<std::size_t>(width) * height * 4)
    throw ImageError("write_png " + path + ": buffer size does not match " + std::to_string(width) +
                     "x" + std::to_string(height));
  write_image(path, width, height, 4, OIIO::TypeDesc::UINT8, rgba.data());
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

std::vector<std::uint8_t> side_by_side(const std::vector<std::uint8_t>& left,
                                       const std::vector<std::uint8_t>& right, int width, int height) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(width) * 2 * height * 4);
  const std::size_t row = static_cast<std::size_t>(width) * 4;
  for (int y = 0; y < height; ++y) {
    std::copy_n(left.begin() + y * row, row, out.begin() + y * 2 * row);
    std::copy_n(right.begin() + y * row, row, out.begin() + y * 2 * row + row);
  }
  return out;
}

}  // namespace px
