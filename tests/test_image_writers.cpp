// The program's own EXR and PNG writers (image/exr_writer.h, image/png_writer.h) against a second
// code path: every file is read back by OpenImageIO (the codec module) and compared value for
// value, floats to the bit; and the pixels equal those of OpenImageIO's own encoder, which wrote
// the files before.
#include "image/exr_writer.h"
#include "image/image_io.h"
#include "image/oiio_codec.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace px {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

std::uint32_t bits_of(float f) {
  std::uint32_t b;
  std::memcpy(&b, &f, sizeof b);
  return b;
}

// Values of every kind a radiance image holds, and some it should not: zeros of both signs,
// denormals, the largest and smallest floats, random magnitudes over many octaves.
ImageRGB varied_image(int width, int height, unsigned seed) {
  ImageRGB image{width, height, std::vector<float>(std::size_t(width) * height * 3)};
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> exponent(-20.0f, 20.0f), sign(-1.0f, 1.0f);
  const float specials[] = {0.0f,
                            -0.0f,
                            std::numeric_limits<float>::denorm_min(),
                            std::numeric_limits<float>::min(),
                            std::numeric_limits<float>::max(),
                            -std::numeric_limits<float>::max(),
                            1.0f};
  for (std::size_t i = 0; i < image.rgb.size(); ++i)
    image.rgb[i] =
        i < std::size(specials) ? specials[i] : (sign(rng) < -0.8f ? -1.0f : 1.0f) * std::exp2(exponent(rng));
  return image;
}

// A smooth image (what ZIP compresses well): a gradient per channel.
ImageRGB smooth_image(int width, int height) {
  ImageRGB image{width, height, std::vector<float>(std::size_t(width) * height * 3)};
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      for (int c = 0; c < 3; ++c)
        image.rgb[(std::size_t(y) * width + x) * 3 + c] = 0.25f * float(c + 1) + float(x) / 64.0f + float(y) / 128.0f;
  return image;
}

void expect_same_bits(const ImageRGB& back, const ImageRGB& written) {
  ASSERT_EQ(back.width, written.width);
  ASSERT_EQ(back.height, written.height);
  ASSERT_EQ(back.rgb.size(), written.rgb.size());
  std::size_t differ = 0, first = 0;
  for (std::size_t i = 0; i < written.rgb.size(); ++i)
    if (bits_of(back.rgb[i]) != bits_of(written.rgb[i]) && differ++ == 0) first = i;
  EXPECT_EQ(differ, 0u) << "first at value " << first << ": " << back.rgb[first] << " read, " << written.rgb[first]
                        << " written";
}

const OiioCodec& oiio() {
  std::string error;
  const OiioCodec* codec = oiio_codec(error);
  if (!codec) throw std::runtime_error(error);
  return *codec;
}

TEST(ExrWriter, OpenImageIOReadsEveryValueBack) {
  TempDir dir;
  // One block and a partial one, several with a short last one, a single pixel, a wide image.
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{1, 1}, {3, 7}, {5, 37}, {4099, 2}, {64, 16}, {2, 33}}) {
    SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h));
    for (const ImageRGB& image : {varied_image(w, h, unsigned(w * 131 + h)), smooth_image(w, h)}) {
      const fs::path p = dir.path() / "a.exr";
      write_exr(p.string(), image);
      expect_same_bits(read_image_rgb(p.string()), image);
      DecodedImage decoded;
      ASSERT_EQ(decode_image_file(p.string(), decoded), "");
      EXPECT_EQ(decoded.channels, 3);
      EXPECT_EQ(decoded.alpha_channel, -1);
      EXPECT_FALSE(decoded.integer_format);
    }
  }
}

// Both kinds of block: a smooth image's blocks are stored compressed (the file is smaller than
// its floats), random bits' are stored as they are (larger compressed); both read back exactly.
TEST(ExrWriter, CompressedAndStoredBlocksBothReadBack) {
  TempDir dir;
  const ImageRGB smooth = smooth_image(256, 40);
  ImageRGB noise{256, 40, std::vector<float>(256 * 40 * 3)};
  std::mt19937 rng(7);
  for (float& v : noise.rgb) {
    const std::uint32_t b = (rng() & 0x7f7fffffu);  // finite: exponent never all ones
    std::memcpy(&v, &b, sizeof v);
  }
  const std::size_t floats_bytes = smooth.rgb.size() * sizeof(float);
  const std::string smooth_bytes = encode_exr(smooth), noise_bytes = encode_exr(noise);
  EXPECT_LT(smooth_bytes.size(), floats_bytes / 2);
  EXPECT_GT(noise_bytes.size(), floats_bytes);
  for (const ImageRGB* image : std::vector<const ImageRGB*>{&smooth, &noise}) {
    const fs::path p = dir.path() / "b.exr";
    write_exr(p.string(), *image);
    expect_same_bits(read_image_rgb(p.string()), *image);
  }
}

// NaN and infinities are stored as they are, as OpenImageIO stored them (the render checks its
// frames for them before writing; a reference or an AOV is written as it is).
TEST(ExrWriter, NonFiniteValuesAreStoredAsTheyAre) {
  TempDir dir;
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  const ImageRGB image{2, 2, {nan, inf, -inf, 1.0f, -nan, 0.5f, inf, inf, inf, 0.0f, nan, 2.0f}};
  const fs::path p = dir.path() / "n.exr";
  write_exr(p.string(), image);
  const ImageRGB back = read_image_rgb(p.string());
  ASSERT_EQ(back.rgb.size(), image.rgb.size());
  for (std::size_t i = 0; i < image.rgb.size(); ++i) {
    SCOPED_TRACE(i);
    if (std::isnan(image.rgb[i]))
      EXPECT_TRUE(std::isnan(back.rgb[i]));
    else
      EXPECT_EQ(back.rgb[i], image.rgb[i]);
  }
  // And what OpenImageIO's encoder keeps of them, ours keeps.
  std::vector<unsigned char> theirs;
  ASSERT_EQ(oiio().encode(p.string(), 2, 2, 3, true, image.rgb.data(), theirs), "");
  const fs::path q = dir.path() / "oiio.exr";
  std::ofstream(q, std::ios::binary)
      .write(reinterpret_cast<const char*>(theirs.data()), std::streamsize(theirs.size()));
  expect_same_bits(back, read_image_rgb(q.string()));
}

// Random bytes; alpha random too, or 255 (`opaque`: every PNG the program writes is).
std::vector<std::uint8_t> random_rgba(int width, int height, unsigned seed, bool opaque) {
  std::vector<std::uint8_t> rgba(std::size_t(width) * height * 4);
  std::mt19937 rng(seed);
  for (std::size_t i = 0; i < rgba.size(); ++i) rgba[i] = std::uint8_t(opaque && i % 4 == 3 ? 255 : rng() & 0xff);
  return rgba;
}

// The bytes as stored: OpenImageIO's decoding keeps straight alpha (decode_image_file) and gives
// the 8-bit values as v / 255.
std::vector<std::uint8_t> png_bytes_read(const fs::path& p, int width, int height) {
  DecodedImage decoded;
  EXPECT_EQ(decode_image_file(p.string(), decoded), "");
  EXPECT_EQ(decoded.width, width);
  EXPECT_EQ(decoded.height, height);
  EXPECT_EQ(decoded.channels, 4);
  EXPECT_TRUE(decoded.integer_format);
  std::vector<std::uint8_t> bytes(decoded.pixels.size());
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = std::uint8_t(std::lround(decoded.pixels[i] * 255.0f));
  return bytes;
}

TEST(PngWriter, OpenImageIOReadsEveryByteBackAsItsOwnEncoderWroteIt) {
  TempDir dir;
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{1, 1}, {3, 7}, {4099, 2}, {40, 30}}) {
    SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h));
    // Alpha is stored as given (straight).
    const fs::path ours = dir.path() / "ours.png", theirs = dir.path() / "theirs.png";
    const std::vector<std::uint8_t> translucent = random_rgba(w, h, unsigned(w + 17 * h), false);
    write_png(ours.string(), w, h, translucent);
    EXPECT_EQ(png_bytes_read(ours, w, h), translucent);
    // OpenImageIO's encoder took colour as premultiplied by alpha (and divided it out); opaque
    // pictures, as the frames are, it wrote as they are.
    const std::vector<std::uint8_t> rgba = random_rgba(w, h, unsigned(w + 17 * h), true);
    write_png(ours.string(), w, h, rgba);
    EXPECT_EQ(png_bytes_read(ours, w, h), rgba);
    std::vector<unsigned char> encoded;
    ASSERT_EQ(oiio().encode(theirs.string(), w, h, 4, false, rgba.data(), encoded), "");
    std::ofstream(theirs, std::ios::binary)
        .write(reinterpret_cast<const char*>(encoded.data()), std::streamsize(encoded.size()));
    EXPECT_EQ(png_bytes_read(ours, w, h), png_bytes_read(theirs, w, h));
  }
}

template <typename F>
std::string image_error_of(F&& f) {
  try {
    f();
  } catch (const ImageError& e) {
    return e.what();
  }
  return "(no ImageError)";
}

TEST(ImageWriters, FailuresAreImageErrorsNamingThePath) {
  TempDir dir;
  const ImageRGB image = smooth_image(4, 4);
  const std::string missing = (dir.path() / "no" / "such" / "folder" / "f").string();
  for (const std::string& m : {image_error_of([&] { write_exr(missing + ".exr", image); }),
                               image_error_of([&] { write_png(missing + ".png", 4, 4, to_srgb8(image)); })})
    EXPECT_NE(m.find(missing), std::string::npos) << m;
  const std::string empty = (dir.path() / "empty").string();
  for (const std::string& m : {image_error_of([&] { write_exr(empty + ".exr", ImageRGB{}); }), image_error_of([&] {
                                 write_exr(empty + ".exr", ImageRGB{2, 2, {1.0f}});
                               }),
                               image_error_of([&] { write_png(empty + ".png", 0, 0, {}); }), image_error_of([&] {
                                 write_png(empty + ".png", 2, 2, {1, 2, 3});
                               })})
    EXPECT_NE(m.find(empty), std::string::npos) << m;
  EXPECT_TRUE(fs::is_empty(dir.path()));
}

}  // namespace
}  // namespace px
