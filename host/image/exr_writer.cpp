// EXR encoding (exr_writer.h): a header of attributes, a table of block offsets, then one block
// per 16 scanlines, each compressed the way OpenEXR's ZIP method is defined (bytes split into
// even and odd halves, each byte replaced by its difference to the one before, zlib).
#include "image/exr_writer.h"

#include <zlib.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <exception>
#include <limits>
#include <thread>
#include <vector>

namespace px {
namespace {

constexpr int kLinesPerBlock = 16;            // ZIP_COMPRESSION's block height
constexpr unsigned char kZipCompression = 3;  // the "compression" attribute's value for ZIP
constexpr std::int32_t kFloatPixelType = 2;   // a channel's pixel type: 0 uint, 1 half, 2 float
constexpr int kZipLevel = 4;  // zlib's level; see docs/measurements.md, "Frames written without OpenImageIO"
constexpr const char* kChannels[] = {"B", "G", "R"};  // sorted by name, as the format stores them
constexpr int kChannelOfStored[] = {2, 1, 0};         // the RGB channel each stored channel holds

// Little-endian values appended to a byte string, as every number in an EXR file is stored.
void put_u8(std::string& out, unsigned v) { out.push_back(static_cast<char>(v & 0xffu)); }
void put_u32(std::string& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) put_u8(out, v >> (8 * i));
}
void put_i32(std::string& out, std::int32_t v) { put_u32(out, static_cast<std::uint32_t>(v)); }
void put_u64(std::string& out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) put_u8(out, static_cast<unsigned>(v >> (8 * i)));
}
void put_f32(std::string& out, float v) {
  std::uint32_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  put_u32(out, bits);
}
void put_name(std::string& out, const char* name) { out.append(name).push_back('\0'); }

void put_attribute(std::string& out, const char* name, const char* type, const std::string& value) {
  put_name(out, name);
  put_name(out, type);
  put_i32(out, static_cast<std::int32_t>(value.size()));
  out += value;
}

std::string box2i(int width, int height) {
  std::string v;
  for (const int c : {0, 0, width - 1, height - 1}) put_i32(v, c);
  return v;
}

std::string f32s(std::initializer_list<float> values) {
  std::string v;
  for (const float f : values) put_f32(v, f);
  return v;
}

// The magic number, the version field (2: single-part scanline, short names) and the header's
// attributes, the required ones only, in the order of their names.
std::string header(int width, int height) {
  std::string out;
  put_u32(out, 20000630u);
  put_u32(out, 2u);
  std::string channels;
  for (const char* name : kChannels) {
    put_name(channels, name);
    put_i32(channels, kFloatPixelType);
    put_u32(channels, 0u);  // pLinear and three reserved bytes
    put_i32(channels, 1);   // x sampling
    put_i32(channels, 1);   // y sampling
  }
  channels.push_back('\0');
  put_attribute(out, "channels", "chlist", channels);
  put_attribute(out, "compression", "compression", std::string(1, static_cast<char>(kZipCompression)));
  put_attribute(out, "dataWindow", "box2i", box2i(width, height));
  put_attribute(out, "displayWindow", "box2i", box2i(width, height));
  put_attribute(out, "lineOrder", "lineOrder", std::string(1, '\0'));  // increasing y
  put_attribute(out, "pixelAspectRatio", "float", f32s({1.0f}));
  put_attribute(out, "screenWindowCenter", "v2f", f32s({0.0f, 0.0f}));
  put_attribute(out, "screenWindowWidth", "float", f32s({1.0f}));
  out.push_back('\0');  // end of the header
  return out;
}

// Block `b`'s pixels as the format lays them out before compression: per scanline, per stored
// channel, the scanline's values.
void gather_block(const ImageRGB& image, int b, std::string& raw) {
  const int first = b * kLinesPerBlock, lines = std::min(kLinesPerBlock, image.height - first);
  const std::size_t w = static_cast<std::size_t>(image.width);
  raw.resize(static_cast<std::size_t>(lines) * 3 * w * 4);
  char* out = raw.data();
  for (int y = first; y < first + lines; ++y) {
    const float* row = image.rgb.data() + static_cast<std::size_t>(y) * w * 3;
    for (const int c : kChannelOfStored)
      for (std::size_t x = 0; x < w; ++x) {
        std::uint32_t bits;
        std::memcpy(&bits, &row[x * 3 + c], sizeof bits);
        for (int i = 0; i < 4; ++i) *out++ = static_cast<char>((bits >> (8 * i)) & 0xffu);
      }
  }
}

// OpenEXR's ZIP method: the even-indexed bytes, then the odd-indexed ones (the low and high
// bytes of the values fall mostly apart), each byte then stored as its difference to the one
// before plus 128, then zlib. The block stays uncompressed when that is not smaller, which is how
// a reader tells the two apart.
std::string zip_block(const std::string& raw, std::string& reordered) {
  const std::size_t n = raw.size();
  reordered.resize(n);
  const std::size_t half = (n + 1) / 2;
  for (std::size_t i = 0; i < n; ++i) reordered[(i % 2 ? half : 0) + i / 2] = raw[i];
  for (std::size_t i = n; i-- > 1;)
    reordered[i] = static_cast<char>(static_cast<unsigned char>(reordered[i]) -
                                     static_cast<unsigned char>(reordered[i - 1]) + 128u);
  uLongf size = compressBound(static_cast<uLong>(n));
  std::string packed(size, '\0');
  const int status = compress2(reinterpret_cast<Bytef*>(packed.data()), &size,
                               reinterpret_cast<const Bytef*>(reordered.data()), static_cast<uLong>(n), kZipLevel);
  if (status != Z_OK) throw ImageError(std::string("zlib could not compress a block: ") + zError(status));
  if (size >= n) return raw;
  packed.resize(size);
  return packed;
}

// Compresses every block, on up to one thread per core (at most 8): the blocks are independent,
// and the compression is nearly all of an EXR's write time.
std::vector<std::string> compressed_blocks(const ImageRGB& image) {
  const int count = (image.height + kLinesPerBlock - 1) / kLinesPerBlock;
  std::vector<std::string> blocks(static_cast<std::size_t>(count));
  std::atomic<int> next{0};
  std::exception_ptr failure;
  std::atomic<bool> failed{false};
  const auto work = [&] {
    std::string raw, reordered;
    try {
      for (int b; !failed && (b = next++) < count;) {
        gather_block(image, b, raw);
        blocks[static_cast<std::size_t>(b)] = zip_block(raw, reordered);
      }
    } catch (...) {
      if (!failed.exchange(true)) failure = std::current_exception();
    }
  };
  // A thread is worth its start only for a few blocks of a frame-sized image.
  const std::size_t bytes = image.rgb.size() * sizeof(float);
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  const unsigned threads = bytes < (1u << 20) ? 1u : std::min({cores, 8u, static_cast<unsigned>(count)});
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);
  return blocks;
}

}  // namespace

std::string encode_exr(const ImageRGB& image) {
  if (image.width <= 0 || image.height <= 0)
    throw ImageError("cannot encode an empty image (" + std::to_string(image.width) + "x" +
                     std::to_string(image.height) + ")");
  if (image.rgb.size() != static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height) * 3)
    throw ImageError("the pixel buffer does not match " + std::to_string(image.width) + "x" +
                     std::to_string(image.height) + " RGB");
  // A block's size is a 32-bit field.
  if (static_cast<std::size_t>(image.width) * 3 * 4 * kLinesPerBlock >
      static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
    throw ImageError("an image " + std::to_string(image.width) + " pixels wide is too wide for an EXR block");
  const std::vector<std::string> blocks = compressed_blocks(image);
  std::string out = header(image.width, image.height);
  std::uint64_t offset = out.size() + blocks.size() * 8;
  for (const std::string& block : blocks) {
    put_u64(out, offset);
    offset += 8 + block.size();  // y and size fields, then the data
  }
  out.reserve(offset);
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    put_i32(out, static_cast<std::int32_t>(b * kLinesPerBlock));
    put_i32(out, static_cast<std::int32_t>(blocks[b].size()));
    out += blocks[b];
  }
  return out;
}

}  // namespace px
