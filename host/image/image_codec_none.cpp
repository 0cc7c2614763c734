// The image codec of a build configured with -DPX_OPENIMAGEIO=OFF: there is none, and every
// call says so (see image_io.h).
#include "image/image_io.h"

namespace px {
namespace {

const char* const kNoCodec = "this build of parallax has no image codec (configured with -DPX_OPENIMAGEIO=OFF)";

}  // namespace

void preload_image_codec() {}

bool image_codec_available() { return false; }

void write_exr(const std::string& path, const ImageRGB&) { throw ImageError("cannot write " + path + ": " + kNoCodec); }

ImageRGB read_image_rgb(const std::string& path) { throw ImageError("cannot read " + path + ": " + kNoCodec); }

void write_png(const std::string& path, int, int, const std::vector<std::uint8_t>&) {
  throw ImageError("cannot write " + path + ": " + kNoCodec);
}

std::string decode_image_file(const std::string&, DecodedImage&) { return kNoCodec; }

std::string decode_image_memory(const unsigned char*, std::size_t, const std::string&, DecodedImage&) {
  return kNoCodec;
}

}  // namespace px
