// The image reader of a build configured with -DPX_OPENIMAGEIO=OFF: there is none, and every
// read says so (see image_io.h). Such a build still writes its frames' EXR and PNG files
// (image_io.cpp), which need no OpenImageIO.
#include "image/image_io.h"

namespace px {
namespace {

const char* const kNoReader =
    "this build of parallax reads no images (configured with -DPX_OPENIMAGEIO=OFF: no textures, no `compare`)";

}  // namespace

void preload_image_codec() {}

bool image_reading_available() { return false; }

ImageRGB read_image_rgb(const std::string& path) { throw ImageError("cannot read " + path + ": " + kNoReader); }

std::string decode_image_file(const std::string&, DecodedImage&) { return kNoReader; }

std::string decode_image_memory(const unsigned char*, std::size_t, const std::string&, DecodedImage&) {
  return kNoReader;
}

}  // namespace px
