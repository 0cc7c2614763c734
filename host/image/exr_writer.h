// OpenEXR encoding of the frames' linear radiance, written by this program without OpenImageIO,
// so that writing a frame loads none of its libraries (image_io.h: OpenImageIO is loaded only to
// read images).
//
// The file is a single-part scanline image (the OpenEXR file layout, openexr.com): channels B, G, R
// (the format sorts channel names) of 32-bit float, ZIP compression (blocks of 16 scanlines,
// zlib), increasing y, data and display windows the whole image: what OpenImageIO wrote for
// write_exr before, so the files read the same in OpenImageIO, OpenEXR, Mitsuba and Python.
// Floats are stored bit for bit, NaN and infinities included.
#pragma once

#include "image/image_io.h"

#include <string>

namespace px {

// The bytes of the EXR file of `image` (rows top to bottom, RGB interleaved). Throws ImageError
// (without a path: the caller names the file) for an empty image or a pixel buffer whose size
// does not match.
std::string encode_exr(const ImageRGB& image);

}  // namespace px
