// bench_image_write: the time to write one frame's files (per eye an EXR and a PNG, and the
// side-by-side stereo PNG, as `render` writes them) with the program's own writers
// (image/exr_writer.h, image/png_writer.h) and with OpenImageIO's encoder (the codec module's,
// which wrote them before), alternated in one process, each written atomically the same way.
// Prints the median and range per writer and per file kind, and checks that both writers' files
// read back to the same pixels.
//
//   build/bench_image_write --image frame_0000_left.exr --repeats 9
//
// Without --image the picture is made up (a gradient with per-pixel noise, as a 1-spp frame has)
// at --width x --height.
#include "app/guarded_main.h"
#include "bench_common.h"
#include "image/exr_writer.h"
#include "image/image_io.h"
#include "image/oiio_codec.h"
#include "image/png_writer.h"
#include "io/atomic_file.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <random>
#include <string_view>

#include <unistd.h>

namespace {

namespace fs = std::filesystem;
using px::bench::median;

px::ImageRGB made_up_image(int width, int height) {
  px::ImageRGB image{width, height, std::vector<float>(std::size_t(width) * height * 3)};
  std::mt19937 rng(1);
  std::exponential_distribution<float> noise(4.0f);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      for (int c = 0; c < 3; ++c)
        image.rgb[(std::size_t(y) * width + x) * 3 + c] =
            (0.2f + 0.6f * float(x) / float(width) + 0.1f * float(c)) * noise(rng) * (y < height / 2 ? 1.0f : 0.5f);
  return image;
}

// One writer: EXR and PNG bytes of a picture.
struct Writer {
  const char* name;
  std::function<std::string(const px::ImageRGB&, const std::string& path)> exr;
  std::function<std::string(int, int, const std::vector<std::uint8_t>&, const std::string& path)> png;
};

std::string oiio_bytes(const std::string& path, int w, int h, int channels, bool floats, const void* pixels) {
  std::string error;
  const px::OiioCodec* codec = px::oiio_codec(error);
  if (!codec) throw std::runtime_error(error);
  std::vector<unsigned char> bytes;
  if (const std::string e = codec->encode(path, w, h, channels, floats, pixels, bytes); !e.empty())
    throw std::runtime_error(e);
  return std::string(bytes.begin(), bytes.end());
}

struct Times {
  std::vector<double> exr, png, frame;
};

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// A frame's files with `writer`: 2 EXRs, 2 PNGs, the stereo PNG; encode and atomic write each.
void write_frame(const Writer& writer, const fs::path& dir, const std::array<px::ImageRGB, 2>& eyes,
                 const std::array<std::vector<std::uint8_t>, 2>& png, const std::vector<std::uint8_t>& stereo,
                 Times& times) {
  const auto frame0 = std::chrono::steady_clock::now();
  double exr_ms = 0, png_ms = 0;
  const auto put = [&](const std::string& path, const std::function<std::string()>& encode, double& ms) {
    const auto t0 = std::chrono::steady_clock::now();
    px::write_file_atomic(path, encode());
    ms += ms_since(t0);
  };
  const int w = eyes[0].width, h = eyes[0].height;
  for (int e = 0; e < 2; ++e) {
    const std::string name = (dir / (std::string(writer.name) + (e ? "_right" : "_left"))).string();
    put(
        name + ".exr", [&] { return writer.exr(eyes[e], name + ".exr"); }, exr_ms);
    put(
        name + ".png", [&] { return writer.png(w, h, png[e], name + ".png"); }, png_ms);
  }
  const std::string stereo_path = (dir / (std::string(writer.name) + "_stereo.png")).string();
  put(
      stereo_path, [&] { return writer.png(2 * w, h, stereo, stereo_path); }, png_ms);
  times.frame.push_back(ms_since(frame0));
  times.exr.push_back(exr_ms);
  times.png.push_back(png_ms);
}

void print_row(const char* writer, const char* what, const std::vector<double>& ms) {
  std::printf("%-12s %-26s %8.1f ms  (%.1f-%.1f)\n", writer, what, median(ms), *std::min_element(ms.begin(), ms.end()),
              *std::max_element(ms.begin(), ms.end()));
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_image_write: a frame's EXR and PNG files, this program's writers against OpenImageIO's"};
  std::string image_path, dir_option;
  int width = 1280, height = 720;
  unsigned repeats = 9;
  app.add_option("--image", image_path, "an image to write (read with OpenImageIO); else a made-up one");
  app.add_option("--width", width, "of the made-up image")->check(CLI::Range(1, 16384))->capture_default_str();
  app.add_option("--height", height, "of the made-up image")->check(CLI::Range(1, 16384))->capture_default_str();
  app.add_option("--repeats", repeats, "frames per writer, alternated")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--dir", dir_option, "where the files go (default: a fresh folder under the temporary one)");
  CLI11_PARSE(app, argc, argv);
  return px::run_guarded([&]() -> int {
    const px::ImageRGB image = image_path.empty() ? made_up_image(width, height) : px::read_image_rgb(image_path);
    // The right eye: the left mirrored, so that the two files differ as a stereo pair's do.
    px::ImageRGB right = image;
    for (int y = 0; y < image.height; ++y)
      for (int x = 0; x < image.width; ++x)
        for (int c = 0; c < 3; ++c)
          right.rgb[(std::size_t(y) * image.width + x) * 3 + c] =
              image.rgb[(std::size_t(y) * image.width + (image.width - 1 - x)) * 3 + c];
    const std::array<px::ImageRGB, 2> eyes{image, right};
    const std::array<std::vector<std::uint8_t>, 2> png{px::to_srgb8(eyes[0]), px::to_srgb8(eyes[1])};
    const std::vector<std::uint8_t> stereo = px::side_by_side(png[0], png[1], image.width, image.height);
    const fs::path dir = dir_option.empty()
                             ? fs::temp_directory_path() / ("bench_image_write." + std::to_string(getpid()))
                             : fs::path(dir_option);
    fs::create_directories(dir);

    const std::array<Writer, 2> writers{
        Writer{"ours", [](const px::ImageRGB& img, const std::string&) { return px::encode_exr(img); },
               [](int w, int h, const std::vector<std::uint8_t>& rgba, const std::string&) {
                 return px::encode_png(w, h, rgba.data());
               }},
        Writer{"openimageio",
               [](const px::ImageRGB& img, const std::string& path) {
                 return oiio_bytes(path, img.width, img.height, 3, true, img.rgb.data());
               },
               [](int w, int h, const std::vector<std::uint8_t>& rgba, const std::string& path) {
                 return oiio_bytes(path, w, h, 4, false, rgba.data());
               }}};
    std::printf("bench_image_write: %dx%d per eye, %u frames per writer, alternated (first of each untimed)\n",
                image.width, image.height, repeats);
    std::array<Times, 2> times;
    for (unsigned r = 0; r <= repeats; ++r)
      for (unsigned k = 0; k < 2; ++k) {
        const unsigned w = (r + k) % 2;  // who goes first alternates too
        Times warmup;
        write_frame(writers[w], dir, eyes, png, stereo, r == 0 ? warmup : times[w]);
      }
    for (unsigned w = 0; w < 2; ++w) {
      print_row(writers[w].name, "frame (2 EXR, 3 PNG)", times[w].frame);
      print_row(writers[w].name, "2 EXR", times[w].exr);
      print_row(writers[w].name, "3 PNG", times[w].png);
    }
    std::printf("frame: ours / openimageio %.2f (medians)\n", median(times[0].frame) / median(times[1].frame));
    // Same pixels from both writers' files, and their sizes.
    bool same = true;
    for (const char* eye : {"_left", "_right"}) {
      const std::string a = (dir / (std::string("ours") + eye)).string(),
                        b = (dir / (std::string("openimageio") + eye)).string();
      same = same && px::read_image_rgb(a + ".exr").rgb == px::read_image_rgb(b + ".exr").rgb;
      px::DecodedImage da, db;
      same = same && px::decode_image_file(a + ".png", da).empty() && px::decode_image_file(b + ".png", db).empty() &&
             da.pixels == db.pixels;
      std::printf("%s: EXR %.2f / %.2f MiB, PNG %.2f / %.2f MiB (ours / openimageio)\n", eye + 1,
                  double(fs::file_size(a + ".exr")) / 1048576.0, double(fs::file_size(b + ".exr")) / 1048576.0,
                  double(fs::file_size(a + ".png")) / 1048576.0, double(fs::file_size(b + ".png")) / 1048576.0);
    }
    std::printf("pixels of both writers' files: %s\n", same ? "identical" : "DIFFER");
    if (dir_option.empty()) fs::remove_all(dir);
    return same ? 0 : 2;
  });
}
