// image_io.h's reading functions in a build with OpenImageIO: each goes through the codec
// module's table (oiio_codec.h). Files are written without it (image_io.cpp).
#include "image/image_io.h"
#include "image/oiio_codec.h"

namespace px {
namespace {

// The table, or ImageError naming what could not be done and why the module is missing.
const OiioCodec& codec_for(const std::string& what) {
  std::string error;
  const OiioCodec* codec = oiio_codec(error);
  if (!codec) throw ImageError(what + ": " + error);
  return *codec;
}

}  // namespace

bool image_reading_available() {
  std::string error;
  return oiio_codec(error) != nullptr;
}

ImageRGB read_image_rgb(const std::string& path) {
  ImageRGB image;
  const std::string error = codec_for("cannot read " + path).read_rgb(path, image);
  if (!error.empty()) throw ImageError(error);
  return image;
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
