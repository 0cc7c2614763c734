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
  // Read at its size in one piece: a stream copy into a growing buffer wrote a 180 MB .glb
  // about three times over into fresh memory. Whatever the file gained since it was measured is
  // read after it (a file that shrank ends where it ends).
  const std::uintmax_t size = fs::file_size(path, ec);
  std::string bytes;
  if (!ec) {
    bytes.resize(static_cast<std::size_t>(size));
    in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    bytes.resize(static_cast<std::size_t>(in.gcount()));
    if (in.bad()) throw SceneError("cannot read " + what);
    if (!in.eof()) in.clear();
  }
  std::ostringstream rest;
  rest << in.rdbuf();
  if (in.bad()) throw SceneError("cannot read " + what);
  bytes += std::move(rest).str();
  return bytes;
}

}  // namespace px
