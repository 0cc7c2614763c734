// The image reader of a build without OpenImageIO (-DPX_OPENIMAGEIO=OFF): every read fails and
// says why, naming the path, while the frames' files are still written (the writers need no
// OpenImageIO). Built beside the default build so that the alternative keeps compiling against
// image_io.h.
#include "image/image_io.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

namespace px {
namespace {

bool says_why(const std::string& message) { return message.find("PX_OPENIMAGEIO=OFF") != std::string::npos; }

template <typename F>
std::string thrown_message(F&& f) {
  try {
    f();
  } catch (const ImageError& e) {
    return e.what();
  }
  return {};
}

std::string file_start(const std::string& path, std::size_t bytes) {
  std::ifstream in(path, std::ios::binary);
  std::string s(bytes, '\0');
  in.read(s.data(), static_cast<std::streamsize>(bytes));
  s.resize(static_cast<std::size_t>(in.gcount()));
  return s;
}

TEST(ImageCodecNone, EveryReadFailsAndSaysWhy) {
  EXPECT_FALSE(image_reading_available());
  DecodedImage decoded;
  EXPECT_TRUE(says_why(decode_image_file("/tmp/any.png", decoded)));
  const unsigned char png_magic[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  EXPECT_TRUE(says_why(decode_image_memory(png_magic, sizeof png_magic, "image.png", decoded)));
  EXPECT_EQ(decoded.width, 0);
  EXPECT_TRUE(decoded.pixels.empty());

  const std::string m = thrown_message([&] { (void)read_image_rgb("/tmp/x.exr"); });
  EXPECT_TRUE(says_why(m)) << m;
  EXPECT_NE(m.find("/tmp/x.exr"), std::string::npos) << m;
}

// The files are written all the same (what they hold is checked against OpenImageIO in
// test_image_writers, in the default build): here, that they are there and of their format.
TEST(ImageCodecNone, FramesFilesAreStillWritten) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("px_codec_none_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const ImageRGB image{3, 2, {0.5f, 0.5f, 0.5f, 1, 2, 3, 4, 5, 6, 0, 0, 0, 7, 8, 9, 0.25f, 0.5f, 1}};
  const std::string exr = (dir / "x.exr").string(), png = (dir / "x.png").string();
  write_exr(exr, image);
  write_png(png, 3, 2, to_srgb8(image));
  EXPECT_EQ(file_start(exr, 4), std::string("\x76\x2f\x31\x01", 4));
  EXPECT_EQ(file_start(png, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  std::filesystem::remove_all(dir);
}

TEST(ImageCodecNone, PreviewEncodingNeedsNoCodec) {
  const ImageRGB image{2, 1, {0.0f, 0.0f, 0.0f, 1.0f, 1.0f, 1.0f}};
  const auto rgba = to_srgb8(image);
  ASSERT_EQ(rgba.size(), 8u);
  EXPECT_EQ(rgba[0], 0);
  EXPECT_EQ(rgba[4], 255);
  EXPECT_EQ(rgba[7], 255);
}

}  // namespace
}  // namespace px
