// Loads the OpenImageIO codec module (oiio_codec.h): from the executable's own folder, else from
// the build folder it was built in (PX_IMAGE_CODEC_MODULE), else PARALLAX_IMAGE_CODEC names it.
#include "image/image_io.h"
#include "image/oiio_codec.h"
#include "io/environment.h"

#include <dlfcn.h>
#include <cstdlib>
#include <string>
#include <vector>
#include <unistd.h>

#include <filesystem>
#include <future>
#include <mutex>

namespace px {
namespace {

constexpr const char* kModuleName = "libparallax_image_oiio.so";

struct Loaded {
  const OiioCodec* codec = nullptr;
  std::string error;
};

std::string executable_folder() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::string() : exe.parent_path().string();
}

Loaded load_module() {
  std::vector<std::string> candidates;
  if (const std::string& path = environment().image_codec; !path.empty()) candidates.push_back(path);
  if (const std::string dir = executable_folder(); !dir.empty()) candidates.push_back(dir + "/" + kModuleName);
#ifdef PX_IMAGE_CODEC_MODULE
  candidates.push_back(PX_IMAGE_CODEC_MODULE);
#endif
  Loaded loaded;
  std::string tried;
  const auto note = [&tried](const std::string& path, const std::string& why) {
    tried += (tried.empty() ? "" : ", ") + path + " (" + why + ")";
  };
  for (const std::string& path : candidates) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) {
      note(path, "absent");
      continue;
    }
    void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      const char* why = dlerror();
      note(path, why ? why : "dlopen failed");
      continue;
    }
    using TableFn = const OiioCodec* (*)();
    const auto table = reinterpret_cast<TableFn>(dlsym(handle, "px_oiio_codec_table"));
    if (!table) {
      note(path, "no px_oiio_codec_table");
      continue;
    }
    loaded.codec = table();  // the module stays loaded for the process's life
    return loaded;
  }
  loaded.error = std::string("the image codec module ") + kModuleName +
                 " could not be loaded: " + (tried.empty() ? "no place to look for it" : tried) +
                 " (set PARALLAX_IMAGE_CODEC to its path)";
  return loaded;
}

std::once_flag g_started;
std::shared_future<Loaded> g_loaded;

void start(std::launch how) {
  std::call_once(g_started, [how] { g_loaded = std::async(how, load_module).share(); });
}

}  // namespace

void preload_image_codec() { start(std::launch::async); }

const OiioCodec* oiio_codec(std::string& error) {
  start(std::launch::deferred);
  const std::shared_future<Loaded> loaded = g_loaded;
  const Loaded& result = loaded.get();
  if (!result.codec) error = result.error;
  return result.codec;
}

}  // namespace px
