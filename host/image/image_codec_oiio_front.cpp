// image_io.h's codec functions in a build with OpenImageIO: each goes through the codec module's
// table (oiio_codec.h), and encoded files are written here, atomically.
#include "image/image_io.h"
#include "image/oiio_codec.h"

#include "io/atomic_file.h"

#include <string_view>

namespace px {
namespace {

// The table, or ImageError naming what could not be done and why the module is missing.
const OiioCodec& codec_for(const std::string& what) {
  std::string error;
  const OiioCodec* codec = oiio_codec(error);
  if (!codec) throw ImageError(what + ": " + error);
  return *codec;
}

void write_encoded(const std::string& path, int width, int height, int channels, bool floats, const void* pixels) {
  std::vector<unsigned char> bytes;
  const std::string error =
      codec_for("cannot write " + path).encode(path, width, height, channels, floats, pixels, bytes);
  if (!error.empty()) throw ImageError(error);
  try {
    write_file_atomic(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
  } catch (const WriteError& e) {
    throw ImageError(e.what());
  }
}

}  // namespace

bool image_codec_available() {
  std::string error;
  return oiio_codec(error) != nullptr;
}

void write_exr(const std::string& path, const ImageRGB& image) {
  write_encoded(path, image.width, image.height, 3, true, image.rgb.data());
}

ImageRGB read_image_rgb(const std::string& path) {
  ImageRGB image;
  const std::string error = codec_for("cannot read " + path).read_rgb(path, image);
  if (!error.empty()) throw ImageError(error);
  return image;
}

void write_png(const std::string& path, int width, int height, const std::vector<std::uint8_t>& rgba) {
  if (rgba.size() != static_cast<std::size_t>(width) * height * 4)
    throw ImageError("write_png " + path + ": buffer size does not match " + std::to_string(width) + "x" +
                     std::to_string(height));
  write_encoded(path, width, height, 4, false, rgba.data());
}

std::string decode_image_file(const std::string& path, DecodedImage& out) {
  std::string error;
  const OiioCodec* codec = oiio_codec(error);
  return codec ? codec->decode_file(path, out) : error;
}

std::string decode_image_memory(const unsigned char* bytes, std::size_t size, const std::string& name,
                                DecodedImage& out) {
  std::string error;
  const OiioCodec* codec = oiio_codec(error);
  return codec ? codec->decode_memory(bytes, size, name, out) : error;
}

}  // namespace px
