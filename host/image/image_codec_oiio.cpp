// The OpenImageIO codec module (libparallax_image_oiio.so): decodes image files for the program,
// which loads it at run time (oiio_codec.h says why), and encodes them for the comparisons of the
// program's own writers (exr_writer.h, png_writer.h) with OpenImageIO's. It writes no file itself.
#include "image/oiio_codec.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>

namespace px {
namespace {

// Encodes into memory (an OIIO IOProxy); the program writes the bytes (write_file_atomic): OIIO's
// own file output does not report every failed write or close (a full disk gave 0-byte files
// and success), and a file written in place is truncated under its final name if the run stops.
std::string encode(const std::string& path, int width, int height, int channels, bool floats, const void* pixels,
                   std::vector<unsigned char>& encoded) {
  const OIIO::TypeDesc type = floats ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
  encoded.clear();
  OIIO::Filesystem::IOVecOutput proxy(encoded);
  auto out = OIIO::ImageOutput::create(path, &proxy);
  if (!out) return "cannot write " + path + ": " + OIIO::geterror();
  if (!out->supports("ioproxy"))
    return "cannot write " + path + ": the " + std::string(out->format_name()) +
           " writer of this OpenImageIO cannot encode into memory";
  OIIO::ImageSpec spec(width, height, channels, type);
  if (!out->open(path, spec)) return "cannot encode " + path + ": " + out->geterror();
  if (!out->write_image(type, pixels)) return "cannot encode " + path + ": " + out->geterror();
  if (!out->close()) return "cannot encode " + path + ": " + out->geterror();
  return {};
}

// Reads the first subimage of an opened input as float. Returns the reason on failure.
std::string read_decoded(OIIO::ImageInput& in, DecodedImage& out) {
  const OIIO::ImageSpec spec = in.spec();
  const int w = spec.width, h = spec.height, nc = spec.nchannels;
  if (w <= 0 || h <= 0 || nc <= 0) return "empty image";
  if (spec.depth > 1) return "volume images are not supported";
  if (std::size_t(w) * std::size_t(h) > (std::size_t(1) << 26)) return "image larger than 8192 x 8192";
  out.pixels.assign(std::size_t(w) * std::size_t(h) * std::size_t(nc), 0.0f);
  if (!in.read_image(0, 0, 0, nc, OIIO::TypeDesc::FLOAT, out.pixels.data())) return in.geterror();
  in.close();
  out.width = w;
  out.height = h;
  out.channels = nc;
  out.alpha_channel = spec.alpha_channel >= 0 && spec.alpha_channel < nc ? spec.alpha_channel : -1;
  out.integer_format = !spec.format.is_floating_point();
  out.tagged_linear = OIIO::Strutil::iequals(spec.get_string_attribute("oiio:ColorSpace"), "Linear");
  return {};
}

// Textures keep their colour unassociated (straight) as stored in the file: cut-outs are
// alpha-tested, not blended, so premultiplying would only darken the edges of leaves.
OIIO::ImageSpec straight_alpha_config() {
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  return config;
}

std::string read_rgb(const std::string& path, ImageRGB& img) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) return "cannot read " + path + ": " + OIIO::geterror();
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.nchannels < 1) return path + ": image has no channels";
  std::vector<float> all(static_cast<std::size_t>(spec.width) * spec.height * spec.nchannels);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, all.data()))
    return "cannot read " + path + ": " + in->geterror();
  img.width = spec.width;
  img.height = spec.height;
  img.rgb.resize(static_cast<std::size_t>(img.width) * img.height * 3);
  for (std::size_t i = 0; i < static_cast<std::size_t>(img.width) * img.height; ++i)
    for (int c = 0; c < 3; ++c) img.rgb[i * 3 + c] = all[i * spec.nchannels + std::min(c, spec.nchannels - 1)];
  return {};
}

std::string decode_file(const std::string& path, DecodedImage& out) {
  const OIIO::ImageSpec config = straight_alpha_config();
  auto in = OIIO::ImageInput::open(path, &config);
  if (!in) return OIIO::geterror();
  return read_decoded(*in, out);
}

std::string decode_memory(const unsigned char* bytes, std::size_t size, const std::string& name, DecodedImage& out) {
  if (size == 0) return "empty image";
  OIIO::Filesystem::IOMemReader memory(bytes, size);
  OIIO::ImageSpec config = straight_alpha_config();
  // The proxy goes in the configuration: OpenImageIO 2.4's open(name, config, proxy) still
  // looks for the file by name.
  void* proxy = &memory;
  config.attribute("oiio:ioproxy", OIIO::TypeDesc::PTR, &proxy);
  auto in = OIIO::ImageInput::open(name, &config);
  if (!in) return OIIO::geterror();
  return read_decoded(*in, out);
}

}  // namespace
}  // namespace px

extern "C" __attribute__((visibility("default"))) const px::OiioCodec* px_oiio_codec_table() {
  static const px::OiioCodec table{px::encode, px::read_rgb, px::decode_file, px::decode_memory};
  return &table;
}
