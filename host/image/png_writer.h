// PNG encoding of the frames' 8-bit pictures through libpng, without OpenImageIO (image_io.h:
// OpenImageIO is loaded only to read images).
//
// 8-bit RGBA, not interlaced, no colour chunks (readers take 8-bit PNG as sRGB, which the pixels
// are), zlib's default level and libpng's filter choice per row. Alpha is stored as given
// (straight, as PNG defines it); OpenImageIO, which wrote the files before, took colour as
// premultiplied and divided alpha out, which for the program's pictures, all opaque (the
// tonemap's alpha is 255, the viewer's screenshot is made opaque), changes nothing.
#pragma once

#include <cstdint>
#include <string>

namespace px {

// The bytes of the PNG file of `rgba` (width * height * 4 bytes, rows top to bottom). Throws
// ImageError (without a path: the caller names the file) for an empty image or when libpng fails.
std::string encode_png(int width, int height, const std::uint8_t* rgba);

}  // namespace px
