// DeviceSet::program serves the frame's kernel files from two programs that include them
// (kernels/pathtrace/scene_kernels.cl and kernels/pipeline/frame_kernels.cl). Every kernel a
// member file defines, read from that file's own embedded source, must come from the program
// served for it; the files of one bundle share one program, and a file outside both is built on
// its own. A file listed for a bundle but not included in it fails here, not in a stage.
#include "cl/device_set.h"
#include "cl/kernel_sources.h"

#include <gtest/gtest.h>

#include <regex>
#include <string>
#include <vector>

namespace px {
namespace {

// The kernels `file` defines itself (not those of the files it includes): lines that declare
// `kernel void NAME(`, after an attribute or nothing, outside comments.
std::vector<std::string> kernels_defined_in(const std::string& file) {
  const std::string& text = kernel_sources().at(file);
  static const std::regex kernel_line(R"((^|\n)[^\n/*]*\b(__)?kernel\s+void\s+(\w+)\s*\()");
  std::vector<std::string> names;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), kernel_line); it != std::sregex_iterator(); ++it)
    names.push_back((*it)[3].str());
  return names;
}

void expect_bundle(DeviceSet& set, const std::vector<std::string>& files) {
  const cl_program shared = set.program(files.front())();
  for (const std::string& file : files) {
    SCOPED_TRACE(file);
    const cl::Program& program = set.program(file);
    EXPECT_EQ(program(), shared) << "one program for the bundle's files";
    const std::vector<std::string> names = kernels_defined_in(file);
    EXPECT_FALSE(names.empty()) << "no kernel found in the file: the pattern no longer matches";
    for (const std::string& name : names) {
      try {
        cl::Kernel kernel(program, name.c_str());
      } catch (const cl::Error& e) {
        ADD_FAILURE() << "kernel " << name << " is not in the program served for " << file << " (" << e.what() << " "
                      << e.err() << ")";
      }
    }
  }
}

TEST(KernelPrograms, EveryMemberFilesKernelsComeFromItsBundle) {
  DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  expect_bundle(set, {"pathtrace/path_trace.cl", "pipeline/gbuffer.cl", "denoise/temporal_gradient.cl"});
  expect_bundle(set, {"pipeline/reproject.cl", "pipeline/tonemap.cl", "pipeline/motion.cl", "pipeline/motion_edges.cl",
                      "denoise/svgf_temporal.cl", "denoise/svgf_atrous.cl", "denoise/svgf_antialias.cl",
                      "denoise/gradient_filter.cl", "denoise/seam_bilateral.cl"});
  // The two bundles are two programs, and a file of neither is its own.
  EXPECT_NE(set.program("pathtrace/path_trace.cl")(), set.program("pipeline/tonemap.cl")());
  const cl_program own = set.program("trace/trace_rays.cl")();
  EXPECT_NE(own, set.program("pathtrace/path_trace.cl")());
  EXPECT_NE(own, set.program("pipeline/tonemap.cl")());
}

// DeviceSet::prebuild builds a program on a thread of its own (SceneOnDevices: the scene's kernels
// while the scene is laid out); program() then serves that build, not a second one, and a build
// that failed throws there, with its log, as a build in program() does.
TEST(KernelPrograms, APrebuiltProgramIsTheOneServedAndItsFailureIsThrownThere) {
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  const std::string options = "-DPX_FEATURES=0x040";
  EXPECT_FALSE(set.has_program("pathtrace/path_trace.cl", options));
  set.prebuild("pathtrace/path_trace.cl", options);
  EXPECT_TRUE(set.has_program("pathtrace/path_trace.cl", options)) << "being built";
  EXPECT_TRUE(set.has_program("pipeline/gbuffer.cl", options)) << "the same bundle, the same program";
  EXPECT_FALSE(set.has_program("pathtrace/path_trace.cl", "-DPX_FEATURES=0x041"));
  const cl::Program& program = set.program("pathtrace/path_trace.cl", options);
  EXPECT_NO_THROW(cl::Kernel(program, "path_trace_pixels"));
  EXPECT_EQ(set.program("denoise/temporal_gradient.cl", options)(), program()) << "served once built";
  set.prebuild("pathtrace/path_trace.cl", options);  // built already: nothing started
  EXPECT_EQ(set.program("pathtrace/path_trace.cl", options)(), program());

  // A build that fails (an option the source cannot take): nothing is thrown at prebuild; the
  // failure, with the build log, comes from program(), as from a build started there.
  const std::string broken = "-DPX_FEATURES=0x040+";
  set.prebuild("pathtrace/path_trace.cl", broken);
  try {
    set.program("pathtrace/path_trace.cl", broken);
    ADD_FAILURE() << "a broken build was served";
  } catch (const ClFailure& e) {
    EXPECT_NE(std::string(e.what()).find("build log"), std::string::npos) << e.what();
  }
  // Asked again, it is built again in program() and fails the same way.
  EXPECT_THROW(set.program("pathtrace/path_trace.cl", broken), ClFailure);

  // Prebuilds run in turn: one that fails does not stop the one asked for after it, and each is
  // served (or thrown) by its own program().
  const std::string after = "-DPX_FEATURES=0x041";
  set.prebuild("pathtrace/path_trace.cl", broken);
  set.prebuild("pathtrace/path_trace.cl", after);
  set.prebuild("pipeline/frame_kernels.cl");
  EXPECT_TRUE(set.has_program("pipeline/reproject.cl")) << "the frame's bundle, asked by its own name";
  EXPECT_NO_THROW(cl::Kernel(set.program("pipeline/tonemap.cl"), "tonemap"));
  EXPECT_NO_THROW(cl::Kernel(set.program("pathtrace/path_trace.cl", after), "path_trace_pixels"));
  EXPECT_THROW(set.program("pathtrace/path_trace.cl", broken), ClFailure);
}

}  // namespace
}  // namespace px
