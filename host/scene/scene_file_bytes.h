// Reads a whole scene input file (OBJ, glTF) into memory with the loaders' error messages:
// SceneError "cannot open <kind> file '<path>': no such file / not a regular file / <errno>".
#pragma once

#include <cstddef>
#include <string>

namespace px {

std::string read_scene_file_bytes(const std::string& path, const char* kind);

// A scene input file's bytes mapped read-only, the same errors as read_scene_file_bytes. A large
// .glb is parsed where it lies in the page cache: read into a string, its bytes were copied into
// as much fresh memory first (112 MB for a 4M-triangle smooth heightfield), and on a virtual
// machine the first touch of fresh pages is most of a large load's time (docs/measurements.md,
// "Fresh memory in the glTF load"). Where the system will not map the file (an empty one, a
// file system without mmap) its bytes are read as before.
//
// The mapping is private and populated when it is made. A file truncated by another program
// while it is mapped would fault where it was cut, as every mapping of a file does; the loaders
// are done with the bytes once the model is parsed (release).
class MappedSceneFile {
 public:
  MappedSceneFile(const std::string& path, const char* kind);
  ~MappedSceneFile() { release(); }
  MappedSceneFile(const MappedSceneFile&) = delete;
  MappedSceneFile& operator=(const MappedSceneFile&) = delete;

  const unsigned char* data() const { return data_; }
  std::size_t size() const { return size_; }
  bool mapped() const { return map_ != nullptr; }
  // The bytes go (unmapped, or the string freed); data() is null and size() 0 from here on.
  void release();

 private:
  const unsigned char* data_ = nullptr;
  std::size_t size_ = 0;
  void* map_ = nullptr;
  std::size_t map_bytes_ = 0;
  std::string read_;  // the bytes where the file was not mapped
};

}  // namespace px
