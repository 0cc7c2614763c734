// The glTF reader: the pre-scan of the JSON before tinygltf sees it, the images decoded for
// tinygltf, and accessors read with every byte checked (gltf_reader.h).
#include "scene/gltf_reader.h"

#include "image/image_io.h"
#include "scene/scene_file_bytes.h"

#include <nlohmann/json.hpp>

#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <sstream>

namespace px::gltf {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr std::size_t kMaxJsonDepth = 128;

// Depth of nesting only: values are not kept.
class DepthScan : public nlohmann::json_sax<json> {
 public:
  bool null() override { return true; }
  bool boolean(bool) override { return true; }
  bool number_integer(number_integer_t) override { return true; }
  bool number_unsigned(number_unsigned_t) override { return true; }
  bool number_float(number_float_t, const string_t&) override { return true; }
  bool string(string_t&) override { return true; }
  bool binary(binary_t&) override { return true; }
  bool key(string_t&) override { return true; }
  bool start_object(std::size_t) override { return open(); }
  bool start_array(std::size_t) override { return open(); }
  bool end_object() override { return --depth_, true; }
  bool end_array() override { return --depth_, true; }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception& e) override {
    error = e.what();
    return false;
  }
  bool too_deep = false;
  std::string error;

 private:
  bool open() {
    if (++depth_ > kMaxJsonDepth) too_deep = true;
    return !too_deep;
  }
  std::size_t depth_ = 0;
};

bool non_negative_integer(const json& v, std::uint64_t& out) {
  if (v.is_number_unsigned()) {
    out = v.get<std::uint64_t>();
    return true;
  }
  if (v.is_number_integer() && v.get<std::int64_t>() >= 0) {
    out = std::uint64_t(v.get<std::int64_t>());
    return true;
  }
  return false;
}

// The file name the decoder is picked by.
std::string image_name_for(const tinygltf::Image& image, const unsigned char* bytes, int size) {
  if (size >= 8 && std::memcmp(bytes, "\x89PNG", 4) == 0) return "image.png";
  if (size >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF) return "image.jpg";
  if (image.mimeType == "image/png") return "image.png";
  if (image.mimeType == "image/jpeg") return "image.jpg";
  const std::string ext = fs::path(image.uri).extension().string();
  return "image" + (ext.empty() ? std::string(".png") : ext);
}

std::string decode_image(tinygltf::Image* image, const unsigned char* bytes, int size) {
  if (size <= 0) return "empty image";
  DecodedImage decoded;
  const std::string error = decode_image_memory(bytes, std::size_t(size), image_name_for(*image, bytes, size), decoded);
  if (!error.empty()) return error;
  image->width = decoded.width;
  image->height = decoded.height;
  image->component = decoded.channels;
  image->bits = 32;
  image->pixel_type = TINYGLTF_COMPONENT_TYPE_FLOAT;
  image->image.resize(decoded.pixels.size() * sizeof(float));
  std::memcpy(image->image.data(), decoded.pixels.data(), image->image.size());
  return {};
}

}  // namespace

std::uint32_t read_u32(const unsigned char* bytes, std::size_t at) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | bytes[at + std::size_t(i)];
  return v;
}

void check_gltf_file_size(const std::string& path, std::size_t bytes) {
  if (bytes >= (std::size_t(1) << 31)) throw SceneError(path + ": glTF file larger than 2 GiB");
}

void prescan_json(const std::string& text, const std::string& path) {
  DepthScan scan;
  json::sax_parse(text, &scan, json::input_format_t::json, /*strict=*/true);
  if (scan.too_deep) throw SceneError(path + ": JSON nested deeper than " + std::to_string(kMaxJsonDepth) + " levels");
  if (!scan.error.empty()) {
    std::string what = scan.error;
    if (const std::size_t close = what.find("] "); what.rfind("[json.", 0) == 0 && close != std::string::npos)
      what = what.substr(close + 2);
    throw SceneError(path + ": invalid glTF JSON: " + what);
  }
  const json doc = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!doc.is_object()) throw SceneError(path + ": invalid glTF: the document must be a JSON object");
  std::vector<std::uint64_t> buffer_length;
  if (auto it = doc.find("buffers"); it != doc.end() && it->is_array())
    for (const json& b : *it) {
      std::uint64_t n = 0;
      const bool ok = b.is_object() && b.contains("byteLength") && non_negative_integer(b["byteLength"], n);
      buffer_length.push_back(ok ? n : 0);
    }
  if (auto it = doc.find("bufferViews"); it != doc.end() && it->is_array())
    for (std::size_t i = 0; i < it->size(); ++i) {
      const json& v = (*it)[i];
      const std::string name = "bufferViews[" + std::to_string(i) + "]";
      if (!v.is_object()) throw SceneError(path + ": " + name + " is not an object");
      std::uint64_t buffer = 0, offset = 0, length = 0;
      if (!v.contains("buffer") || !non_negative_integer(v["buffer"], buffer) || buffer >= buffer_length.size())
        throw SceneError(path + ": " + name + " names no existing buffer");
      if (v.contains("byteOffset") && !non_negative_integer(v["byteOffset"], offset))
        throw SceneError(path + ": " + name + ".byteOffset is not a non-negative integer");
      if (!v.contains("byteLength") || !non_negative_integer(v["byteLength"], length))
        throw SceneError(path + ": " + name + ".byteLength is missing or not a non-negative integer");
      if (offset > buffer_length[buffer] || length > buffer_length[buffer] - offset)
        throw SceneError(path + ": " + name + " (bytes " + std::to_string(offset) + " + " + std::to_string(length) +
                         ") reaches past the end of buffer " + std::to_string(buffer) + " (" +
                         std::to_string(buffer_length[buffer]) + " bytes)");
    }
}

std::string one_line(const std::string& text) {
  std::string out;
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line)) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (line.empty()) continue;
    out += (out.empty() ? "" : "; ") + line;
  }
  return out;
}

bool load_image_lenient(tinygltf::Image* image, const int index, std::string*, std::string*, int, int,
                        const unsigned char* bytes, int size, void* user) {
  const std::string error = decode_image(image, bytes, size);
  if (error.empty()) return true;
  auto* log = static_cast<ImageLoadLog*>(user);
  std::string what = one_line(error);
  if (what.size() > 160) what = what.substr(0, 160) + "...";
  log->failed.push_back("image " + std::to_string(index) + (image->name.empty() ? "" : " '" + image->name + "'") +
                        " (" + what + ")");
  image->image.clear();
  image->width = image->height = image->component = -1;
  return true;
}

// ---------------------------------------------------------------------------------------------
// Accessors.

std::vector<glm::vec4> Reader::floats(int index, std::initializer_list<int> types, const std::string& what,
                                      bool allow_integer) const {
  const tinygltf::Accessor& a = accessor(index, what);
  if (std::find(types.begin(), types.end(), a.type) == types.end())
    fail(what + " (accessor " + std::to_string(index) + ") has an unexpected element type");
  const int nc = tinygltf::GetNumComponentsInType(std::uint32_t(a.type));
  if (a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT && !allow_integer)
    fail(what + " (accessor " + std::to_string(index) + ") must hold floats");
  std::vector<glm::vec4> out(a.count, glm::vec4(0.0f));
  for_each_element(a, index, what, [&](std::size_t i, const unsigned char* p) {
    for (int c = 0; c < nc && c < 4; ++c) out[i][c] = component(a, p, c);
  });
  return out;
}

std::vector<glm::vec3> Reader::vec3s(int index, const std::string& what) const {
  const tinygltf::Accessor& a = accessor(index, what);
  if (a.type != TINYGLTF_TYPE_VEC3)
    fail(what + " (accessor " + std::to_string(index) + ") has an unexpected element type");
  if (a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
    fail(what + " (accessor " + std::to_string(index) + ") must hold floats");
  std::vector<glm::vec3> out(a.count, glm::vec3(0.0f));
  for_each_element(a, index, what, [&](std::size_t i, const unsigned char* p) { std::memcpy(&out[i], p, 12); });
  return out;
}

std::vector<glm::vec2> Reader::vec2s(int index, const std::string& what) const {
  const tinygltf::Accessor& a = accessor(index, what);
  if (a.type != TINYGLTF_TYPE_VEC2)
    fail(what + " (accessor " + std::to_string(index) + ") has an unexpected element type");
  std::vector<glm::vec2> out(a.count, glm::vec2(0.0f));
  if (a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT)
    for_each_element(a, index, what, [&](std::size_t i, const unsigned char* p) { std::memcpy(&out[i], p, 8); });
  else
    for_each_element(a, index, what, [&](std::size_t i, const unsigned char* p) {
      out[i] = glm::vec2(component(a, p, 0), component(a, p, 1));
    });
  return out;
}

std::vector<glm::dmat4> Reader::matrices(int index, const std::string& what) const {
  const tinygltf::Accessor& a = accessor(index, what);
  if (a.type != TINYGLTF_TYPE_MAT4 || a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
    fail(what + " (accessor " + std::to_string(index) + ") must hold MAT4 floats");
  std::vector<glm::dmat4> out(a.count, glm::dmat4(1.0));
  for_each_element(a, index, what, [&](std::size_t i, const unsigned char* p) {
    for (int c = 0; c < 16; ++c) glm::value_ptr(out[i])[c] = component(a, p, c);
  });
  return out;
}

std::vector<std::uint32_t> Reader::indices(int index, const std::string& what) const {
  const tinygltf::Accessor& a = accessor(index, what);
  if (a.type != TINYGLTF_TYPE_SCALAR || (a.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
                                         a.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
                                         a.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT))
    fail(what + " (accessor " + std::to_string(index) + ") must be unsigned integer scalars");
  std::vector<std::uint32_t> out(a.count, 0);
  for_each_element(a, index, what, [&](std::size_t i, const unsigned char* p) {
    switch (a.componentType) {
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: out[i] = p[0]; break;
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        std::uint16_t v;
        std::memcpy(&v, p, 2);
        out[i] = v;
        break;
      }
      default: std::memcpy(&out[i], p, 4);
    }
  });
  return out;
}

const tinygltf::Accessor& Reader::accessor(int index, const std::string& what) const {
  if (index < 0 || std::size_t(index) >= model_.accessors.size())
    fail(what + " names accessor " + std::to_string(index) + ", which does not exist");
  const tinygltf::Accessor& a = model_.accessors[std::size_t(index)];
  if (a.sparse.isSparse)
    fail(what + " (accessor " + std::to_string(index) + ") is sparse, which parallax does not support");
  // Bounded before anything is allocated for it: an accessor with a buffer view is checked
  // against its bytes later (every element takes at least one), one without is all zeros.
  std::size_t limit = std::size_t(1) << 24;
  if (a.bufferView >= 0) {
    limit = 0;
    for (const tinygltf::Buffer& b : model_.buffers) limit += b.data.size();
  }
  if (a.count > limit)
    fail(what + " (accessor " + std::to_string(index) + ") claims " + std::to_string(a.count) +
         " elements, more than its data can hold");
  return a;
}

float Reader::component(const tinygltf::Accessor& a, const unsigned char* p, int c) {
  switch (a.componentType) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
      float v;
      std::memcpy(&v, p + 4 * c, 4);
      return v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return a.normalized ? p[c] / 255.0f : float(p[c]);
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      const float v = float(std::int8_t(p[c]));
      return a.normalized ? std::max(v / 127.0f, -1.0f) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      std::uint16_t v;
      std::memcpy(&v, p + 2 * c, 2);
      return a.normalized ? v / 65535.0f : float(v);
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      std::int16_t v;
      std::memcpy(&v, p + 2 * c, 2);
      return a.normalized ? std::max(v / 32767.0f, -1.0f) : float(v);
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
      std::uint32_t v;
      std::memcpy(&v, p + 4 * c, 4);
      return float(v);
    }
    default: return 0.0f;
  }
}

template <typename F>
void Reader::for_each_element(const tinygltf::Accessor& a, int index, const std::string& what, F&& visit) const {
  const std::string name = what + " (accessor " + std::to_string(index) + ")";
  const int csize = tinygltf::GetComponentSizeInBytes(std::uint32_t(a.componentType));
  const int nc = tinygltf::GetNumComponentsInType(std::uint32_t(a.type));
  if (csize <= 0 || nc <= 0) fail(name + " has an invalid component or element type");
  if (a.count == 0) return;
  if (a.bufferView < 0) return;
  if (std::size_t(a.bufferView) >= model_.bufferViews.size())
    fail(name + " names buffer view " + std::to_string(a.bufferView) + ", which does not exist");
  const tinygltf::BufferView& view = model_.bufferViews[std::size_t(a.bufferView)];
  if (view.buffer < 0 || std::size_t(view.buffer) >= model_.buffers.size())
    fail(name + ": its buffer view names no existing buffer");
  const std::vector<unsigned char>& data = model_.buffers[std::size_t(view.buffer)].data;
  const std::uint64_t elem = std::uint64_t(csize) * std::uint64_t(nc);
  const std::uint64_t stride = view.byteStride == 0 ? elem : view.byteStride;
  if (stride < elem) fail(name + ": byteStride " + std::to_string(view.byteStride) + " is smaller than an element");
  // In 64 bits none of these overflows: count and stride are below 2^32 or refused first.
  if (a.count > data.size() || stride > 252 + elem)
    fail(name + ": " + std::to_string(a.count) + " elements do not fit in its buffer view");
  const std::uint64_t view_end = std::uint64_t(view.byteOffset) + view.byteLength;
  if (view.byteOffset > data.size() || view_end > data.size())
    fail(name + ": its buffer view reaches past the end of buffer " + std::to_string(view.buffer) + " (" +
         std::to_string(data.size()) + " bytes loaded)");
  if (a.byteOffset > view.byteLength || std::uint64_t(a.byteOffset) + (a.count - 1) * stride + elem > view.byteLength)
    fail(name + ": " + std::to_string(a.count) + " elements from byte " + std::to_string(a.byteOffset) +
         " reach past the end of its buffer view (" + std::to_string(view.byteLength) + " bytes)");
  const unsigned char* base = data.data() + view.byteOffset + a.byteOffset;
  for (std::size_t i = 0; i < a.count; ++i) visit(i, base + i * stride);
}

}  // namespace px::gltf
