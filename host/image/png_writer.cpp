// PNG encoding through libpng (png_writer.h), into memory: the caller writes the file atomically.
#include "image/png_writer.h"

#include "image/image_io.h"

#include <png.h>
#include <zlib.h>

#include <cstdio>
#include <vector>

namespace px {
namespace {

// What libpng's callbacks reach: the bytes so far, and the reason of a failure.
struct Sink {
  std::string* bytes = nullptr;
  char error[256] = "";
};

void append(png_structp png, png_bytep data, png_size_t size) {
  auto* sink = static_cast<Sink*>(png_get_io_ptr(png));
  try {
    sink->bytes->append(reinterpret_cast<const char*>(data), size);
  } catch (...) {  // no C++ exception may cross libpng's C frames
    png_error(png, "out of memory");
  }
}

void flush(png_structp) {}

// libpng's errors end in a longjmp back to encode_rows (its setjmp), after the reason is kept.
void on_error(png_structp png, png_const_charp message) {
  auto* sink = static_cast<Sink*>(png_get_error_ptr(png));
  std::snprintf(sink->error, sizeof sink->error, "%s", message ? message : "libpng failed");
  png_longjmp(png, 1);
}

void on_warning(png_structp, png_const_charp) {}

// The libpng calls, in a frame that holds no C++ object with a destructor: libpng's errors
// leave it by longjmp. Returns false on failure, with the reason in sink.error.
bool encode_rows(int width, int height, const png_bytep* rows, Sink* sink) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, sink, on_error, on_warning);
  if (!png) {
    std::snprintf(sink->error, sizeof sink->error, "libpng could not start");
    return false;
  }
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    std::snprintf(sink->error, sizeof sink->error, "libpng could not start");
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_set_write_fn(png, sink, append, flush);
  // zlib's default level and strategy with libpng's filter choice per row, as OpenImageIO wrote
  // them (libpng's own default strategy for filtered rows, Z_FILTERED, is slower on renders).
  png_set_compression_level(png, Z_DEFAULT_COMPRESSION);
  png_set_compression_strategy(png, Z_DEFAULT_STRATEGY);
  png_set_IHDR(png, info, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height), 8,
               PNG_COLOR_TYPE_RGB_ALPHA, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  png_write_image(png, const_cast<png_bytepp>(rows));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

std::string encode_png(int width, int height, const std::uint8_t* rgba) {
  if (width <= 0 || height <= 0)
    throw ImageError("cannot encode an empty image (" + std::to_string(width) + "x" + std::to_string(height) + ")");
  std::vector<png_bytep> rows(static_cast<std::size_t>(height));
  const std::size_t stride = static_cast<std::size_t>(width) * 4;
  for (std::size_t y = 0; y < rows.size(); ++y) rows[y] = const_cast<png_bytep>(rgba + y * stride);
  std::string bytes;
  Sink sink;
  sink.bytes = &bytes;
  if (!encode_rows(width, height, rows.data(), &sink)) throw ImageError(std::string("libpng: ") + sink.error);
  return bytes;
}

}  // namespace px
