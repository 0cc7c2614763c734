// The image codec of a build without OpenImageIO (-DPX_OPENIMAGEIO=OFF): every entry point
// fails and says why, naming the path, and nothing else depends on it. Built beside the default
// build so that the alternative keeps compiling against image_io.h.
#include "image/image_io.h"

#include <gtest/gtest.h>

#include <string>

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

TEST(ImageCodecNone, EveryCallFailsAndSaysWhy) {
  EXPECT_FALSE(image_codec_available());
  DecodedImage decoded;
  EXPECT_TRUE(says_why(decode_image_file("/tmp/any.png", decoded)));
  const unsigned char png_magic[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  EXPECT_TRUE(says_why(decode_image_memory(png_magic, sizeof png_magic, "image.png", decoded)));
  EXPECT_EQ(decoded.width, 0);
  EXPECT_TRUE(decoded.pixels.empty());

  const ImageRGB image{1, 1, {0.5f, 0.5f, 0.5f}};
  for (const std::string& m : {thrown_message([&] { write_exr("/tmp/x.exr", image); }),
                               thrown_message([&] { write_png("/tmp/x.png", 1, 1, to_srgb8(image)); }),
                               thrown_message([&] { (void)read_image_rgb("/tmp/x.exr"); })}) {
    EXPECT_TRUE(says_why(m)) << m;
    EXPECT_NE(m.find("/tmp/x."), std::string::npos) << m;
  }
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
