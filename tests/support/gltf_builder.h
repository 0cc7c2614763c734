// A glTF 2.0 document assembled by a test: accessors over one binary buffer, written as a
// .gltf with the buffer embedded as a data URI. Tests build the files they load.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace px::test {

std::string base64(const std::string& bytes);

struct GltfBuilder {
  nlohmann::json doc = {{"asset", {{"version", "2.0"}}}};
  std::string bin;

  // An accessor of `count` elements of glTF `type` ("SCALAR", "VEC3", "MAT4"...) over `data`.
  int floats(const std::vector<float>& data, const char* type, std::size_t count);
  int uint16s(const std::vector<std::uint16_t>& data, const char* type, std::size_t count);
  // Appends to doc[key] (an array, made on first use) and returns the index.
  int add(const char* key, nlohmann::json item);
  // The document with its buffer as a data URI.
  std::string text() const;

 private:
  int accessor(const std::string& bytes, int component, std::size_t count, const char* type);
};

}  // namespace px::test
