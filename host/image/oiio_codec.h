// The OpenImageIO codec as a table of four functions, loaded at run time.
//
// OpenImageIO's Debian build pulls in about 260 shared libraries; linked into the program, the
// dynamic linker resolved them all before main, for every run, `parallax --help` included
// (docs/measurements.md, "The image codec as a module"). So the codec lives in a module of its
// own (libparallax_image_oiio.so, image_codec_oiio.cpp) beside the executable, which
// image_codec_module.cpp opens at the first image read (a texture of the scene, `compare`'s
// files), or earlier on another thread (preload_image_codec, image_io.h). The program writes its
// frames' files without it (exr_writer.h, png_writer.h), so a scene without textures never loads
// it. image_codec_oiio_front.cpp implements image_io.h's reading on top of the table.
//
// The table's functions return an empty string on success, else the reason; they never throw.
// Both sides are built by this project with one compiler and standard library, so the table
// may hold C++ types.
#pragma once

#include "image/image_io.h"

#include <cstddef>
#include <string>
#include <vector>

namespace px {

struct OiioCodec {
  // Encodes pixels (float or 8-bit, `channels` interleaved, rows top to bottom) into the bytes
  // of the file format `path`'s extension names. The program's files no longer go through it:
  // bench_image_write times this program's writers against it (OpenImageIO's, as files were
  // written before), and the tests compare the two writers' files.
  std::string (*encode)(const std::string& path, int width, int height, int channels, bool floats, const void* pixels,
                        std::vector<unsigned char>& bytes);
  std::string (*read_rgb)(const std::string& path, ImageRGB& out);
  std::string (*decode_file)(const std::string& path, DecodedImage& out);
  std::string (*decode_memory)(const unsigned char* bytes, std::size_t size, const std::string& name,
                               DecodedImage& out);
};

// The module's table, loading it on first use (thread-safe); null with the reason in `error`
// when it cannot be loaded.
const OiioCodec* oiio_codec(std::string& error);

}  // namespace px

// The one symbol the module exports.
extern "C" const px::OiioCodec* px_oiio_codec_table();
