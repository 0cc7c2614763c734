#include "scene/scene_file_bytes.h"

#include "scene/scene.h"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace px {

std::string read_scene_file_bytes(const std::string& path, const char* kind) {
  namespace fs = std::filesystem;
  const std::string what = std::string(kind) + " file '" + path + "'";
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  // A folder or a device would "open" and read as empty or block: refuse anything else.
  if (ec || !fs::exists(st)) throw SceneError("cannot open " + what + ": no such file");
  if (!fs::is_regular_file(st)) throw SceneError("cannot open " + what + ": not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError("cannot open " + what + ": " + std::strerror(errno));
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw SceneError("cannot read " + what);
  return std::move(ss).str();
}

}  // namespace px
