// Image files: linear float EXR (radiance, for references and error figures) and 8-bit PNG
// (what a person looks at), and the reading of images (textures, `compare`'s files).
//
// The frames' files are written by this program itself (exr_writer.h, png_writer.h: zlib and
// libpng), in every build. Reading goes through OpenImageIO (image_codec_oiio_front.cpp, the codec
// itself a module loaded at run time: oiio_codec.h), so a run whose scene has no texture never
// loads its libraries. Every function throws ImageError with the path on failure.
//
// A build configured with -DPX_OPENIMAGEIO=OFF has no image reader (image_codec_none.cpp): it
// renders, measures and writes its frames' files, but loads no texture and reads no image
// (`compare`, references), and says so. It exists for machines without the Debian packages,
// e.g. a GPU machine the project is carried to as a self-contained bundle.
#pragma once

#include <cstddef>
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

// Starts loading the image reader on a thread of its own where it is loaded at run time
// (OpenImageIO's module, oiio_codec.h), so that it is ready by the first image read; a no-op
// where it is not, and when it is loaded or loading already. Never fails: a reader that cannot be
// loaded says so at its first use.
void preload_image_codec();

// False in a build without an image reader: read_image_rgb and decode_image_* then fail with a
// message that says so (decode_image_* return it, read_image_rgb throws ImageError). Writing
// needs no reader.
bool image_reading_available();

// Written atomically (io/atomic_file.h): 32-bit float RGB, ZIP-compressed (exr_writer.h); NaN and
// infinities are stored as they are.
void write_exr(const std::string& path, const ImageRGB& image);
ImageRGB read_image_rgb(const std::string& path);  // any format OIIO reads; alpha dropped

// 8-bit RGBA, rows top to bottom (png_writer.h), written atomically.
void write_png(const std::string& path, int width, int height, const std::vector<std::uint8_t>& rgba);

// The pixels of a decoded image, channel-interleaved float, rows top to bottom, as stored (no
// colour conversion; straight, unassociated alpha).
struct DecodedImage {
  int width = 0;
  int height = 0;
  int channels = 0;
  int alpha_channel = -1;       // the channel the file names as alpha, or -1
  bool integer_format = false;  // stored as integers (8/16-bit colour is usually sRGB-encoded)
  bool tagged_linear = false;   // the file says its colour space is linear
  std::vector<float> pixels;    // width * height * channels
};

// Decodes an image file, or an encoded image held in memory (`name` only picks the decoder by
// its extension). Returns an empty string on success, else the reason. Refuses volumes and
// images of more than 8192 x 8192 pixels (as float RGBA that is already 1 GiB per device copy).
std::string decode_image_file(const std::string& path, DecodedImage& out);
std::string decode_image_memory(const unsigned char* bytes, std::size_t size, const std::string& name,
                                DecodedImage& out);

// Linear -> sRGB-encoded 8 bit with exposure scale and clamp (a preview tonemap for host-side
// images; the pipeline's tonemap stage runs on the devices).
std::vector<std::uint8_t> to_srgb8(const ImageRGB& image, float exposure = 1.0f);

// Places `left` and `right` side by side (same size) — the stereo PNG layout.
std::vector<std::uint8_t> side_by_side(const std::vector<std::uint8_t>& left, const std::vector<std::uint8_t>& right,
                                       int width, int height);

}  // namespace px
