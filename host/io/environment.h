// The environment variables parallax reads: this module is the only place in host/ that reads a
// PARALLAX_ variable (XDG_CACHE_HOME, HOME, PATH, DISPLAY and OMPI_* are other programs' and are
// read where they are used). Each is read once, at the first call of environment(), into a typed
// field; a value the module does not understand is reported (a warning on stderr naming the
// variable, once) and the default kept, never silently ignored. Options given on the command
// line take precedence where both exist (--platform over PARALLAX_PLATFORM).
//
//   variable                     field              what it is for
//   PARALLAX_PLATFORM            platform           substring of the OpenCL platform to use when
//                                                   DeviceOptions::platform is empty
//   PARALLAX_POCL_LAUNCH_GUARD   pocl_launch_guard  `off`: no PoclLaunchGuard on PoCL CPU devices
//                                                   (to reproduce the abort it prevents)
//   PARALLAX_MAX_ALLOC_BYTES     max_alloc_bytes    a positive number of bytes: lowers the devices'
//                                                   CL_DEVICE_MAX_MEM_ALLOC_SIZE for DeviceScene
//                                                   (to test its refusal of a too-large buffer)
//   PARALLAX_IMAGE_CODEC         image_codec        path of the image codec module, tried first
//   PARALLAX_BVH_CACHE           bvh_cache          `off`: no BVH cache (nor device layout cache)
//   PARALLAX_CACHE_DIR           cache_dir          the caches' folder (default: XDG_CACHE_HOME/
//                                                   parallax, else HOME/.cache/parallax)
//   PARALLAX_HUGE_PAGES          huge_pages         `off`: large allocations not advised onto
//                                                   transparent huge pages
//   PARALLAX_INDEXED_SHADING     indexed_shading    `off`: smooth meshes keep 64-byte shading
//                                                   records, not indexed ones (the layout
//                                                   before them, to compare against)
//
// The switches take one word for off, `off`; `on` (or an empty value) is the default.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace px {

struct Environment {
  std::string platform;             // PARALLAX_PLATFORM ("" = none)
  bool pocl_launch_guard = true;    // PARALLAX_POCL_LAUNCH_GUARD
  std::size_t max_alloc_bytes = 0;  // PARALLAX_MAX_ALLOC_BYTES (0 = the devices' own limit)
  std::string image_codec;          // PARALLAX_IMAGE_CODEC ("" = none)
  bool bvh_cache = true;            // PARALLAX_BVH_CACHE
  std::string cache_dir;            // PARALLAX_CACHE_DIR ("" = the default folder)
  bool huge_pages = true;           // PARALLAX_HUGE_PAGES
  bool indexed_shading = true;      // PARALLAX_INDEXED_SHADING
  // One line per variable whose value was not understood, naming it, the value and what was
  // kept instead.
  std::vector<std::string> problems;
};

// The variables as `lookup` (a getenv) gives them, parsed; no side effects. For tests.
Environment parse_environment(const std::function<const char*(const char*)>& lookup);

// The process's environment, read (and any problems written to stderr) at the first call.
const Environment& environment();

// Reads the environment again: for tests that set a variable at run time (tests/support/
// scoped_env.h). Not thread-safe against concurrent environment() readers.
void reload_environment_for_tests();

}  // namespace px
