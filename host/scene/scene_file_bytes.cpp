#include "scene/scene_file_bytes.h"

#include "scene/scene.h"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

namespace px {
namespace {

// "<kind> file '<path>'" for the errors, once the path is known to name a regular file: a
// folder or a device would "open" and read as empty or block, so anything else is refused.
std::string regular_file_named(const std::string& path, const char* kind) {
  namespace fs = std::filesystem;
  const std::string what = std::string(kind) + " file '" + path + "'";
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec || !fs::exists(st)) throw SceneError("cannot open " + what + ": no such file");
  if (!fs::is_regular_file(st)) throw SceneError("cannot open " + what + ": not a regular file");
  return what;
}

}  // namespace

std::string read_scene_file_bytes(const std::string& path, const char* kind) {
  namespace fs = std::filesystem;
  const std::string what = regular_file_named(path, kind);
  std::error_code ec;
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

MappedSceneFile::MappedSceneFile(const std::string& path, const char* kind) {
  const std::string what = regular_file_named(path, kind);
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw SceneError("cannot open " + what + ": " + std::strerror(errno));
  struct stat info {};
  if (::fstat(fd, &info) == 0 && info.st_size > 0) {
    const auto bytes = static_cast<std::size_t>(info.st_size);
    void* map = ::mmap(nullptr, bytes, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
    if (map != MAP_FAILED) {
      map_ = map;
      map_bytes_ = bytes;
      data_ = static_cast<const unsigned char*>(map);
      size_ = bytes;
    }
  }
  ::close(fd);
  if (map_) return;
  read_ = read_scene_file_bytes(path, kind);
  data_ = reinterpret_cast<const unsigned char*>(read_.data());
  size_ = read_.size();
}

void MappedSceneFile::release() {
  if (map_) ::munmap(map_, map_bytes_);
  map_ = nullptr;
  map_bytes_ = 0;
  std::string().swap(read_);
  data_ = nullptr;
  size_ = 0;
}

}  // namespace px
