// glTF files before conversion (gltf_loader.cpp reads them through these): the checks made on
// the raw JSON before tinygltf parses it, the image decoder handed to tinygltf, and Reader, which
// reads accessors with every byte checked against the buffers actually loaded.
#pragma once

#include "scene/scene.h"

#include <tiny_gltf.h>

#include <glm/glm.hpp>

#include <cstdint>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

namespace px::gltf {

// A GLB file starts with this magic number; its first chunk is the JSON document.
inline constexpr std::uint32_t kGlbMagic = 0x46546C67;      // "glTF"
inline constexpr std::uint32_t kGlbJsonChunk = 0x4E4F534A;  // "JSON"

// The little-endian 32-bit word at byte `at` of `bytes`.
std::uint32_t read_u32(const unsigned char* bytes, std::size_t at);

// SceneError when the file's bytes are more than tinygltf takes (it takes the length as an
// unsigned int).
void check_gltf_file_size(const std::string& path, std::size_t bytes);

// The checks tinygltf does not make before it reads through the document's numbers.
// SceneError naming `path` and what is wrong.
void prescan_json(const std::string& text, const std::string& path);

// tinygltf's messages, one per line, joined for a one-line error.
std::string one_line(const std::string& text);

// Images are decoded from memory by the image codec (image_io.h), as the OBJ path's textures are, into float
// RGBA kept in tinygltf's Image (bits 32). An image it cannot decode (KTX2, WebP...) or one
// too large loses its texture, with a warning, instead of failing the whole file.
struct ImageLoadLog {
  std::vector<std::string> failed;
};

// tinygltf's image loader (LoadImageDataFunction; `user` is an ImageLoadLog): decodes through
// the image codec; an image it cannot decode is logged and left empty, and loading goes on.
bool load_image_lenient(tinygltf::Image* image, const int index, std::string*, std::string*, int, int,
                        const unsigned char* bytes, int size, void* user);

// ---------------------------------------------------------------------------------------------
// Accessors.

class Reader {
 public:
  Reader(const tinygltf::Model& model, std::string path) : model_(model), path_(std::move(path)) {}

  [[noreturn]] void fail(const std::string& what) const { throw SceneError(path_ + ": " + what); }

  // Elements of accessor `index` as up to 4 floats each (integer components converted as the
  // spec says: normalized -> [0, 1] / [-1, 1], else the plain value). `types` lists the
  // accepted TINYGLTF_TYPE_*; `what` names the accessor in errors.
  std::vector<glm::vec4> floats(int index, std::initializer_list<int> types, const std::string& what,
                                bool allow_integer) const;
  // A VEC3 float accessor (POSITION, NORMAL) and a VEC2 accessor (TEXCOORD_0, integer
  // components converted as floats() converts them), read into their own element types: what
  // floats() reads, without a 16-byte element and a copy each (a large mesh's load touches that
  // much less fresh memory).
  std::vector<glm::vec3> vec3s(int index, const std::string& what) const;
  std::vector<glm::vec2> vec2s(int index, const std::string& what) const;

  // Elements of a MAT4 float accessor (column-major, as glTF stores them).
  std::vector<glm::dmat4> matrices(int index, const std::string& what) const;

  std::vector<std::uint32_t> indices(int index, const std::string& what) const;

  std::size_t count(int index, const std::string& what) const { return accessor(index, what).count; }

 private:
  const tinygltf::Accessor& accessor(int index, const std::string& what) const;
  static float component(const tinygltf::Accessor& a, const unsigned char* p, int c);

  // Calls visit(i, pointer to element i) after checking every byte read lies in the buffer.
  // An accessor without a buffer view is all zeros (the spec's rule): visit is not called.
  template <typename F>
  void for_each_element(const tinygltf::Accessor& a, int index, const std::string& what, F&& visit) const;

  const tinygltf::Model& model_;
  std::string path_;
};

}  // namespace px::gltf
