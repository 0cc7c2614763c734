// Output files and folders: atomic writes (a failed write is an error naming the file and
// leaves no file, temporary or truncated), the --out claim (lock, stale files, folders a failed
// run created), and the scene-file guards against hostile input.
#include "app/guarded_main.h"
#include "app/output_dir.h"
#include "image/image_io.h"
#include "io/atomic_file.h"
#include "io/interrupt.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <sstream>

#include <sys/resource.h>
#include <unistd.h>

namespace px {
namespace {

namespace fs = std::filesystem;

using test::TempDir;

std::set<std::string> names_in(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

std::string read_all(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no exception)";
}

// A file-size limit makes write() fail (EFBIG) past `bytes`, as a full disk does (ENOSPC), without
// needing a small file system. SIGXFSZ is ignored meanwhile, or the kernel would kill the test.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    getrlimit(RLIMIT_FSIZE, &old_);
    old_handler_ = std::signal(SIGXFSZ, SIG_IGN);
    rlimit limited = old_;
    limited.rlim_cur = bytes;
    ok_ = setrlimit(RLIMIT_FSIZE, &limited) == 0;
  }
  ~FileSizeLimit() {
    setrlimit(RLIMIT_FSIZE, &old_);
    std::signal(SIGXFSZ, old_handler_);
  }
  bool ok() const { return ok_; }

 private:
  rlimit old_{};
  void (*old_handler_)(int) = SIG_DFL;
  bool ok_ = false;
};

// Whether a library whose file name contains `name` is mapped into this process.
bool library_mapped(const std::string& name) {
  std::ifstream maps("/proc/self/maps");
  std::string line;
  while (std::getline(maps, line))
    if (line.find(name) != std::string::npos) return true;
  return false;
}

// OpenImageIO's codec is a module loaded at run time (image/oiio_codec.h) and only to read, so a
// process that writes its frames' files holds none of its ~260 libraries; the first read (or
// preload_image_codec, on another thread) loads it, and the image round-trips through it.
// CTest runs each test in a process of its own; run with the others in one process, an earlier
// test may have loaded it already, and only the round trip is checked.
TEST(ImageCodecModule, OpenImageIOLoadsOnlyToReadAnImage) {
#ifndef PX_IMAGE_CODEC_MODULE_BUILD
  GTEST_SKIP() << "a build without OpenImageIO";
#endif
  const bool loaded_before = library_mapped("libparallax_image_oiio");
  if (!loaded_before) {
    EXPECT_FALSE(library_mapped("libOpenImageIO")) << "linked into the program";
  }
  TempDir dir;
  const fs::path p = dir.path() / "a.exr";
  ImageRGB image;
  image.width = 3;
  image.height = 2;
  image.rgb = {0.f,    0.25f,  0.5f,   1.f,  2.f,  4.f,  8.f, 16.f, 32.f,
               0.125f, 0.375f, 0.625f, 1.5f, 2.5f, 3.5f, 7.f, 9.f,  11.f};
  write_exr(p.string(), image);
  write_png((dir.path() / "a.png").string(), 3, 2, to_srgb8(image));
  if (!loaded_before) {
    EXPECT_FALSE(library_mapped("libOpenImageIO")) << "writing loaded it";
    EXPECT_FALSE(library_mapped("libparallax_image_oiio")) << "writing loaded it";
  }
  preload_image_codec();
  const ImageRGB back = read_image_rgb(p.string());
  EXPECT_TRUE(library_mapped("libOpenImageIO"));
  EXPECT_TRUE(library_mapped("libparallax_image_oiio"));
  ASSERT_EQ(back.width, 3);
  ASSERT_EQ(back.height, 2);
  EXPECT_EQ(back.rgb, image.rgb);
}

// An error after a Ctrl-C is the interruption's consequence (a kernel build whose compiler
// removed its files on the signal): the run ends as interrupted, 130, naming the error; without
// a signal the same error is exit 1. Each in a child process, whose interrupt state is its own
// (started afresh: the earlier tests leave threads that a forked copy could wait on for ever).
TEST(GuardedMain, AnErrorAfterAnInterruptEndsTheRunAsInterrupted) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  const auto failing = [] { return run_guarded([]() -> int { throw std::runtime_error("the build failed"); }); };
  EXPECT_EXIT(std::exit(failing()), ::testing::ExitedWithCode(1), "error: the build failed");
  EXPECT_EXIT(
      {
        simulate_interrupt_for_testing(SIGINT);
        std::exit(failing());
      },
      ::testing::ExitedWithCode(130), "interrupted \\(SIGINT\\); then: the build failed");
}

TEST(AtomicFile, WritesTheWholeFileAndNoTemporary) {
  TempDir dir;
  const fs::path p = dir.path() / "a.json";
  const std::string text(100000, 'x');
  write_file_atomic(p.string(), text);
  EXPECT_EQ(read_all(p), text);
  EXPECT_EQ(names_in(dir.path()), std::set<std::string>{"a.json"});
}

TEST(AtomicFile, FailedWriteNamesTheFileKeepsTheOldOneAndLeavesNoTemporary) {
  TempDir dir;
  const fs::path p = dir.path() / "frame_0000_left.exr";
  write_file_atomic(p.string(), "old contents");
  std::string msg;
  {
    FileSizeLimit limit(4096);
    if (!limit.ok()) GTEST_SKIP() << "cannot set RLIMIT_FSIZE here";
    msg = error_of([&] { write_file_atomic(p.string(), std::string(64 * 1024, 'y')); });
  }
  EXPECT_NE(msg.find(p.string()), std::string::npos) << msg;
  EXPECT_NE(msg.find("write"), std::string::npos) << msg;
  EXPECT_EQ(read_all(p), "old contents");
  EXPECT_EQ(names_in(dir.path()), std::set<std::string>{"frame_0000_left.exr"});
}

TEST(AtomicFile, FailedImageWriteIsAnImageErrorAndNoFile) {
  TempDir dir;
  ImageRGB img;
  img.width = 64;
  img.height = 64;
  img.rgb.resize(64 * 64 * 3);
  std::mt19937 rng(1);
  for (float& v : img.rgb) v = std::uniform_real_distribution<float>(0.0f, 4.0f)(rng);  // incompressible
  const fs::path exr = dir.path() / "big.exr", png = dir.path() / "big.png";
  std::string exr_msg, png_msg;
  {
    FileSizeLimit limit(1024);
    if (!limit.ok()) GTEST_SKIP() << "cannot set RLIMIT_FSIZE here";
    try {
      write_exr(exr.string(), img);
    } catch (const ImageError& e) {
      exr_msg = e.what();
    }
    try {
      write_png(png.string(), img.width, img.height, to_srgb8(img));
    } catch (const ImageError& e) {
      png_msg = e.what();
    }
  }
  EXPECT_NE(exr_msg.find(exr.string()), std::string::npos) << exr_msg;
  EXPECT_NE(png_msg.find(png.string()), std::string::npos) << png_msg;
  EXPECT_TRUE(names_in(dir.path()).empty());
  // And without the limit the same image is written and reads back.
  write_exr(exr.string(), img);
  const ImageRGB back = read_image_rgb(exr.string());
  EXPECT_EQ(back.rgb, img.rgb);
}

TEST(AtomicFile, MissingFolderIsAnErrorNamingTheFile) {
  TempDir dir;
  const fs::path p = dir.path() / "no" / "such" / "r.json";
  const std::string msg = error_of([&] { write_file_atomic(p.string(), "{}"); });
  EXPECT_NE(msg.find(p.string()), std::string::npos) << msg;
}

TEST(AtomicFile, UncommittedStreamLeavesNothing) {
  TempDir dir;
  const fs::path p = dir.path() / "report.json";
  {
    AtomicFileWriter w(p.string());
    w.write("{\"frames\": [");
    EXPECT_FALSE(fs::exists(p)) << "the final name appears only at commit";
  }
  EXPECT_TRUE(names_in(dir.path()).empty());
  AtomicFileWriter w(p.string());
  w.write("{}");
  w.commit();
  EXPECT_EQ(read_all(p), "{}");
}

TEST(OutputDir, SecondClaimIsRefusedUntilTheFirstEnds) {
  TempDir dir;
  const fs::path out = dir.path() / "out";
  {
    OutputDir first(out.string(), false);
    EXPECT_TRUE(fs::exists(out / OutputDir::kLockName));
    const std::string msg = error_of([&] { OutputDir second(out.string(), false); });
    EXPECT_NE(msg.find("in use"), std::string::npos) << msg;
    EXPECT_NE(msg.find("pid " + std::to_string(::getpid())), std::string::npos) << msg;
    // Not even --overwrite takes a folder another run holds.
    EXPECT_NE(error_of([&] { OutputDir second(out.string(), true); }).find("in use"), std::string::npos);
    write_file_atomic(first.file("frame_0000_left.exr"), "x");
  }
  EXPECT_FALSE(fs::exists(out / OutputDir::kLockName)) << "the lock is removed at exit";
  EXPECT_NE(error_of([&] { OutputDir again(out.string(), false); }).find("not empty"), std::string::npos);
}

TEST(OutputDir, LockOfAProcessThatIsGoneIsExplained) {
  TempDir dir;
  std::ofstream(dir.path() / OutputDir::kLockName) << "pid 2147483646\n";
  const std::string msg = error_of([&] { OutputDir claim(dir.path().string(), true); });
  EXPECT_NE(msg.find("no longer running"), std::string::npos) << msg;
  EXPECT_NE(msg.find(OutputDir::kLockName), std::string::npos) << msg;
}

TEST(OutputDir, OverwriteRemovesStaleFramesAndTemporariesOnly) {
  TempDir dir;
  for (const char* name : {"frame_0000_left.exr", "frame_0000_stereo.png", "frame_0011_right.png",
                           ".frame_0003_left.exr.4242.partial", "notes.txt", "frame_notes.txt"})
    std::ofstream(dir.path() / name) << "old";
  EXPECT_NE(error_of([&] { OutputDir claim(dir.path().string(), false, is_render_frame_file); }).find("not empty"),
            std::string::npos);
  {
    OutputDir claim(dir.path().string(), true, is_render_frame_file);
    EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"notes.txt", "frame_notes.txt", OutputDir::kLockName}));
  }
  EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"notes.txt", "frame_notes.txt"}));
}

TEST(OutputDir, FoldersAFailedRunCreatedAreRemovedIfEmpty) {
  TempDir dir;
  const fs::path out = dir.path() / "a" / "b";
  { OutputDir claim(out.string(), false); }
  EXPECT_FALSE(fs::exists(dir.path() / "a"));
  {
    OutputDir claim(out.string(), false);
    write_file_atomic(claim.file("frame_0000_left.exr"), "x");
  }
  EXPECT_TRUE(fs::exists(out / "frame_0000_left.exr")) << "a folder holding output stays";
}

TEST(OutputDir, RenderFrameNames) {
  EXPECT_TRUE(is_render_frame_file("frame_0000_left.exr"));
  EXPECT_TRUE(is_render_frame_file("frame_12345_stereo.png"));
  EXPECT_TRUE(is_render_frame_file("frame_0003_right_albedo.exr"));
  EXPECT_TRUE(is_render_frame_file("frame_0003_left_normal.exr"));
  EXPECT_FALSE(is_render_frame_file("frame_0003_stereo_normal.exr"));
  EXPECT_FALSE(is_render_frame_file("frame_0003_left_albedo.png"));
  EXPECT_FALSE(is_render_frame_file("frame_0000_left.exr.bak"));
  EXPECT_FALSE(is_render_frame_file("my_frame_0000_left.exr"));
  EXPECT_FALSE(is_render_frame_file("frame_00_left.exr"));
}

}  // namespace
}  // namespace px
