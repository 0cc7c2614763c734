// glTF 2.0 loading (.gltf with external or data-URI buffers, and binary .glb): tinygltf (the
// Debian shared library) parses the file, OpenImageIO decodes its images; this file validates
// and converts.
//
// tinygltf trusts the file's numbers: an accessor or buffer view reaching past its buffer, an
// index beyond the vertex count, a node hierarchy with a cycle, or JSON nested deep enough to
// overflow its recursive value conversion would read out of bounds or crash. So:
//   - before tinygltf sees the file, a pre-scan bounds the JSON nesting depth and checks that
//     every buffer view lies inside its buffer's declared byteLength (image decoding reads
//     through buffer views without checking);
//   - every accessor read here is checked against the bytes actually loaded, every index
//     against the vertex count, and the node walk refuses nodes reached twice.
//
// Material mapping onto the renderer's model (scene.h):
//   baseColorFactor (+ baseColorTexture)  -> diffuse (+ diffuse_texture), scaled by 1 - metallic
//   metallicFactor                        -> specular = mix(0.04, base colour, metallic)
//                                            (a mostly metallic material's specular is also
//                                            tinted by the base colour texture)
//   roughnessFactor                       -> GGX alpha = roughness^2 (0 = perfect mirror)
//   alphaMode MASK + alphaCutoff          -> an alpha cut-out texture (the OBJ map_d path)
//   emissiveFactor x KHR_materials_emissive_strength -> emission (an emissive texture, which
//                                            the renderer cannot vary across a surface, is
//                                            averaged to one colour)
//   normalTexture                         -> normal_texture, normal_scale
//   KHR_materials_transmission >= 0.5     -> smooth dielectric, index from KHR_materials_ior
//   doubleSided                           -> emitters light both faces
//   COLOR_0 (vertex colours)              -> Scene::vertex_colours, multiplying the diffuse colour
//   KHR_lights_punctual directional       -> the sun (the first one; point and spot lights are named)
// Everything else the file asks for is named in one warning line.
//
// Motion: a file with animations keeps its node hierarchy, meshes, skins and clips in
// Scene::rig (scene_rig.h), which poses the scene at any time; translation, rotation and scale
// channels play with STEP, LINEAR and CUBICSPLINE interpolation, and skins (JOINTS_0 and
// WEIGHTS_0, inverse bind matrices) are evaluated on the host. A file without animations is
// posed once here (skins included, at their rest pose) and keeps no rig. Morph targets are named
// in the warning line.
//
// Instances: in a static file, a mesh that several nodes draw is stored once in its own space,
// with one matrix per node (Scene::instancing), and traversed through a two-level BVH; in a file
// that moves, so is each rigid mesh on a node that a clip moves (its matrix changes, its
// triangles do not). SceneLoadOptions::instancing = false draws copies instead.
#include "image/image_io.h"
#include "scene/primitives.h"
#include "scene/scene_rig.h"
#include "scene/scene_file_bytes.h"
#include "scene/scene_loader.h"

#include <tiny_gltf.h>

#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <functional>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <set>
#include <sstream>

namespace px {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr std::size_t kMaxJsonDepth = 128;
constexpr std::uint32_t kGlbMagic = 0x46546C67;      // "glTF"
constexpr std::uint32_t kGlbJsonChunk = 0x4E4F534A;  // "JSON"

std::uint32_t read_u32(const std::string& bytes, std::size_t at) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | std::uint8_t(bytes[at + std::size_t(i)]);
  return v;
}

std::string read_binary_file(const std::string& path) {
  std::string bytes = read_scene_file_bytes(path, "glTF");
  // tinygltf takes the length as an unsigned int.
  if (bytes.size() >= (std::size_t(1) << 31)) throw SceneError(path + ": glTF file larger than 2 GiB");
  return bytes;
}

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

// The checks tinygltf does not make before it reads through the document's numbers.
void prescan_json(const std::string& text, const std::string& path) {
  DepthScan scan;
  json::sax_parse(text, &scan, json::input_format_t::json, /*strict=*/true);
  if (scan.too_deep)
    throw SceneError(path + ": JSON nested deeper than " + std::to_string(kMaxJsonDepth) + " levels");
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

// tinygltf's messages, one per line, joined for a one-line error.
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

// Images are decoded from memory by the image codec (image_io.h), as the OBJ path's textures are, into float
// RGBA kept in tinygltf's Image (bits 32). An image it cannot decode (KTX2, WebP...) or one
// too large loses its texture, with a warning, instead of failing the whole file.
struct ImageLoadLog {
  std::vector<std::string> failed;
};

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

class Reader {
 public:
  Reader(const tinygltf::Model& model, std::string path) : model_(model), path_(std::move(path)) {}

  [[noreturn]] void fail(const std::string& what) const { throw SceneError(path_ + ": " + what); }

  // Elements of accessor `index` as up to 4 floats each (integer components converted as the
  // spec says: normalized -> [0, 1] / [-1, 1], else the plain value). `types` lists the
  // accepted TINYGLTF_TYPE_*; `what` names the accessor in errors.
  std::vector<glm::vec4> floats(int index, std::initializer_list<int> types, const std::string& what,
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

  // Elements of a MAT4 float accessor (column-major, as glTF stores them).
  std::vector<glm::dmat4> matrices(int index, const std::string& what) const {
    const tinygltf::Accessor& a = accessor(index, what);
    if (a.type != TINYGLTF_TYPE_MAT4 || a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
      fail(what + " (accessor " + std::to_string(index) + ") must hold MAT4 floats");
    std::vector<glm::dmat4> out(a.count, glm::dmat4(1.0));
    for_each_element(a, index, what, [&](std::size_t i, const unsigned char* p) {
      for (int c = 0; c < 16; ++c) glm::value_ptr(out[i])[c] = component(a, p, c);
    });
    return out;
  }

  std::vector<std::uint32_t> indices(int index, const std::string& what) const {
    const tinygltf::Accessor& a = accessor(index, what);
    if (a.type != TINYGLTF_TYPE_SCALAR ||
        (a.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
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

  std::size_t count(int index, const std::string& what) const { return accessor(index, what).count; }

 private:
  const tinygltf::Accessor& accessor(int index, const std::string& what) const {
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

  static float component(const tinygltf::Accessor& a, const unsigned char* p, int c) {
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

  // Calls visit(i, pointer to element i) after checking every byte read lies in the buffer.
  // An accessor without a buffer view is all zeros (the spec's rule): visit is not called.
  template <typename F>
  void for_each_element(const tinygltf::Accessor& a, int index, const std::string& what, F&& visit) const {
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
    if (a.byteOffset > view.byteLength ||
        std::uint64_t(a.byteOffset) + (a.count - 1) * stride + elem > view.byteLength)
      fail(name + ": " + std::to_string(a.count) + " elements from byte " + std::to_string(a.byteOffset) +
           " reach past the end of its buffer view (" + std::to_string(view.byteLength) + " bytes)");
    const unsigned char* base = data.data() + view.byteOffset + a.byteOffset;
    for (std::size_t i = 0; i < a.count; ++i) visit(i, base + i * stride);
  }

  const tinygltf::Model& model_;
  std::string path_;
};

// ---------------------------------------------------------------------------------------------
// Textures.

float srgb_to_linear(float c) {
  c = std::clamp(c, 0.0f, 1.0f);
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

// An image as linear RGBA floats (sRGB decoded when `srgb`: glTF's colour textures are sRGB
// whatever their bit depth), or false when it has no pixels.
bool image_pixels(const tinygltf::Image& img, bool srgb, Texture& tex) {
  if (img.width <= 0 || img.height <= 0 || img.component <= 0 || img.bits != 32) return false;
  const std::size_t n = std::size_t(img.width) * std::size_t(img.height), nc = std::size_t(img.component);
  if (img.image.size() < n * nc * sizeof(float)) return false;
  const float* px = reinterpret_cast<const float*>(img.image.data());
  tex.width = img.width;
  tex.height = img.height;
  tex.rgba.assign(n * 4, 1.0f);
  auto finite01 = [](float v) { return std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f; };
  for (std::size_t i = 0; i < n; ++i) {
    float v[4] = {0.0f, 0.0f, 0.0f, 1.0f};
    for (std::size_t c = 0; c < nc && c < 4; ++c) v[c] = finite01(px[i * nc + c]);
    if (nc < 3) {  // grey (+ alpha)
      v[3] = nc == 2 ? v[1] : 1.0f;
      v[1] = v[2] = v[0];
    }
    for (int c = 0; c < 3; ++c) tex.rgba[4 * i + std::size_t(c)] = srgb ? srgb_to_linear(v[c]) : v[c];
    tex.rgba[4 * i + 3] = v[3];
  }
  return true;
}

// What the file asks for but is not rendered, gathered into one warning line.
class Unsupported {
 public:
  void add(const std::string& feature, const std::string& where = "") {
    auto [it, inserted] = features_.try_emplace(feature);
    if (inserted) order_.push_back(feature);
    if (!where.empty() && std::find(it->second.begin(), it->second.end(), where) == it->second.end())
      it->second.push_back(where);
  }
  std::string line(const std::string& path) const {
    if (order_.empty()) return {};
    std::string out = path + ": ignored glTF features (not rendered):";
    for (std::size_t i = 0; i < order_.size(); ++i) {
      const auto& where = features_.at(order_[i]);
      out += (i ? ", " : " ") + order_[i];
      if (where.empty()) continue;
      out += " (";
      const std::size_t shown = std::min<std::size_t>(where.size(), 3);
      for (std::size_t k = 0; k < shown; ++k) out += (k ? ", " : "") + where[k];
      if (where.size() > shown) out += ", +" + std::to_string(where.size() - shown) + " more";
      out += ")";
    }
    return out;
  }

 private:
  std::vector<std::string> order_;
  std::map<std::string, std::vector<std::string>> features_;
};

class Converter {
 public:
  Converter(const tinygltf::Model& model, std::string path, const SceneLoadOptions& options, Scene& scene)
      : model_(model), path_(std::move(path)), options_(options), scene_(scene), read_(model_, path_) {}

  void materials() {
    for (std::size_t i = 0; i < model_.materials.size(); ++i) scene_.materials.push_back(material(i));
  }

  void geometry(bool* has_camera) {
    std::vector<int> roots;
    if (!model_.scenes.empty()) {
      int s = model_.defaultScene;
      if (s < 0 || std::size_t(s) >= model_.scenes.size()) s = 0;
      roots = model_.scenes[std::size_t(s)].nodes;
      if (model_.scenes.size() > 1)
        unsupported_.add("scenes other than the default (" + std::to_string(model_.scenes.size() - 1) + ")");
    } else {
      // No scene: every node that is no other node's child is a root.
      std::vector<char> child(model_.nodes.size(), 0);
      for (const tinygltf::Node& n : model_.nodes)
        for (int c : n.children)
          if (c >= 0 && std::size_t(c) < child.size()) child[std::size_t(c)] = 1;
      for (std::size_t i = 0; i < model_.nodes.size(); ++i)
        if (!child[i]) roots.push_back(int(i));
    }
    // A scene that moves keeps its hierarchy, meshes, skins and clips (scene_rig.h) and is
    // posed from them; so is one with skins, posed once at rest. Any other is flattened here.
    bool skinned = false;
    for (const tinygltf::Node& n : model_.nodes) skinned |= n.skin >= 0 && n.mesh >= 0;
    if (!model_.animations.empty() || skinned) {
      rig_ = std::make_shared<SceneRig>();
      rig_->nodes.resize(model_.nodes.size());
    }
    visited_.assign(model_.nodes.size(), 0);
    for (int r : roots) visit(r, glm::dmat4(1.0), -1, "scene", 0);
    if (has_camera) *has_camera = camera_found_;
    if (rig_) {
      skins();
      animations();
      pose_at_rest();
    } else {
      place_meshes();
    }
  }

  void finish() {
    for (const std::string& e : model_.extensionsUsed)
      if (!handled_extension(e)) unsupported_.add("extension " + e);
    if (!failed_images_.empty()) {
      std::string list;
      for (const std::string& f : failed_images_) list += (list.empty() ? "" : ", ") + f;
      scene_.stats.warnings.push_back(path_ + ": cannot decode " + list + "; textures using them are ignored");
    }
    if (const std::string line = unsupported_.line(path_); !line.empty()) scene_.stats.warnings.push_back(line);
  }

  static bool handled_extension(const std::string& e) {
    return e == "KHR_materials_emissive_strength" || e == "KHR_materials_transmission" || e == "KHR_materials_ior" ||
           e == "KHR_lights_punctual";
  }

  std::vector<std::string> failed_images_;
  // Frees the model's buffer bytes (load_gltf owns the model); called once a static scene's
  // meshes are decoded. A later read of an accessor would then fail as out of range, not
  // read stale bytes.
  std::function<void()> release_buffers_;

 private:
  // --- materials -----------------------------------------------------------------------------

  static double number_in(const tinygltf::ExtensionMap& ext, const std::string& name, const std::string& key,
                          double fallback) {
    const auto it = ext.find(name);
    if (it == ext.end() || !it->second.IsObject() || !it->second.Has(key)) return fallback;
    const tinygltf::Value& v = it->second.Get(key);
    return v.IsNumber() || v.IsInt() ? v.GetNumberAsDouble() : fallback;
  }

  static float finite_clamped(double v, float lo, float hi, float fallback) {
    return std::isfinite(v) ? std::clamp(float(v), lo, hi) : fallback;
  }

  // The image behind texture `index`, or null (with a warning when the reason is not already
  // given elsewhere). `what` names the slot, `mat` the material.
  const tinygltf::Image* texture_image(const tinygltf::TextureInfo& info, const std::string& what,
                                       const std::string& mat) {
    return texture_image(info.index, info.texCoord, info.extensions, what, mat);
  }
  const tinygltf::Image* texture_image(int index, int tex_coord, const tinygltf::ExtensionMap& ext,
                                       const std::string& what, const std::string& mat) {
    if (index < 0) return nullptr;
    if (std::size_t(index) >= model_.textures.size()) {
      scene_.stats.warnings.push_back(path_ + ": material '" + mat + "': " + what + " names texture " +
                                      std::to_string(index) + ", which does not exist; ignoring it");
      return nullptr;
    }
    const tinygltf::Texture& t = model_.textures[std::size_t(index)];
    if (tex_coord != 0) unsupported_.add("texCoord sets other than TEXCOORD_0", mat);
    if (ext.count("KHR_texture_transform")) unsupported_.add("KHR_texture_transform", mat);
    for (const auto& [name, value] : t.extensions) unsupported_.add("texture extension " + name, mat);
    if (t.sampler >= 0 && std::size_t(t.sampler) < model_.samplers.size()) {
      const tinygltf::Sampler& s = model_.samplers[std::size_t(t.sampler)];
      if (s.wrapS != TINYGLTF_TEXTURE_WRAP_REPEAT || s.wrapT != TINYGLTF_TEXTURE_WRAP_REPEAT)
        unsupported_.add("sampler wrap modes other than REPEAT", mat);
      if (s.magFilter == TINYGLTF_TEXTURE_FILTER_NEAREST)
        unsupported_.add("NEAREST magnification filter (textures are filtered bilinearly)", mat);
    }
    if (t.source < 0 || std::size_t(t.source) >= model_.images.size()) {
      scene_.stats.warnings.push_back(path_ + ": material '" + mat + "': " + what + " texture " +
                                      std::to_string(index) + " has no image; ignoring it");
      return nullptr;
    }
    const tinygltf::Image& img = model_.images[std::size_t(t.source)];
    if (img.image.empty() || img.width <= 0 || img.height <= 0) {
      // Undecodable images are listed once by finish(); a missing file is said here.
      if (!img.uri.empty() && img.uri.rfind("data:", 0) != 0)
        scene_.stats.warnings.push_back(path_ + ": material '" + mat + "': " + what + " image '" + img.uri +
                                        "' not found or unreadable; ignoring it");
      return nullptr;
    }
    return &img;
  }

  int colour_texture(const tinygltf::Image* img, bool srgb) {
    if (!img) return -1;
    const auto key = std::make_pair(img, srgb);
    if (auto it = cache_.find(key); it != cache_.end()) return it->second;
    Texture tex;
    tex.path = img->uri.rfind("data:", 0) == 0 ? path_ + " (embedded image)" : img->uri;
    if (tex.path.empty()) tex.path = path_ + " (image '" + img->name + "')";
    if (!image_pixels(*img, srgb, tex)) return cache_[key] = -1;
    scene_.textures.push_back(std::move(tex));
    return cache_[key] = int(scene_.textures.size()) - 1;
  }

  Material material(std::size_t index) {
    const tinygltf::Material& m = model_.materials[index];
    Material out;
    out.name = m.name.empty() ? "material " + std::to_string(index) : m.name;
    const std::string& name = out.name;
    const tinygltf::PbrMetallicRoughness& pbr = m.pbrMetallicRoughness;

    glm::vec4 base(1.0f);
    for (std::size_t c = 0; c < 4 && c < pbr.baseColorFactor.size(); ++c)
      base[int(c)] = finite_clamped(pbr.baseColorFactor[c], 0.0f, 1.0f, 1.0f);
    const float metallic = finite_clamped(pbr.metallicFactor, 0.0f, 1.0f, 1.0f);
    const float roughness = finite_clamped(pbr.roughnessFactor, 0.0f, 1.0f, 1.0f);
    const tinygltf::Image* base_image = texture_image(pbr.baseColorTexture, "baseColorTexture", name);
    const int base_texture = colour_texture(base_image, /*srgb=*/true);

    const glm::vec3 rgb(base);
    out.diffuse = rgb * (1.0f - metallic);
    out.diffuse_texture = base_texture;
    out.specular = glm::mix(glm::vec3(0.04f), rgb, metallic);
    if (metallic >= 0.5f) out.specular_texture = base_texture;
    out.roughness = roughness * roughness;
    if (pbr.metallicRoughnessTexture.index >= 0) unsupported_.add("metallicRoughnessTexture (factors used)", name);

    // Transmission: a smooth dielectric (the renderer's glass has no roughness or tint texture).
    const double transmission = number_in(m.extensions, "KHR_materials_transmission", "transmissionFactor", 0.0);
    if (transmission >= 0.5) {
      out.dielectric = true;
      const double ior = number_in(m.extensions, "KHR_materials_ior", "ior", 1.5);
      out.ior = std::isfinite(ior) && ior >= 1.0 && ior <= 10.0 ? float(ior) : 1.5f;
      out.transmission = rgb;
      if (roughness > 0.0f) unsupported_.add("rough transmission (rendered smooth)", name);
    } else if (transmission > 0.0) {
      unsupported_.add("KHR_materials_transmission below 0.5 (rendered opaque)", name);
    }

    // Emission.
    glm::vec3 emissive(0.0f);
    for (std::size_t c = 0; c < 3 && c < m.emissiveFactor.size(); ++c)
      emissive[int(c)] = finite_clamped(m.emissiveFactor[c], 0.0f, 1.0f, 0.0f);
    const double strength = number_in(m.extensions, "KHR_materials_emissive_strength", "emissiveStrength", 1.0);
    emissive *= std::isfinite(strength) && strength >= 0.0 ? float(std::min(strength, 1e30)) : 1.0f;
    if (const tinygltf::Image* img = texture_image(m.emissiveTexture, "emissiveTexture", name)) {
      Texture tex;
      if (image_pixels(*img, /*srgb=*/true, tex)) {
        glm::dvec3 sum(0.0);
        for (std::size_t i = 0; i < tex.rgba.size(); i += 4) sum += glm::dvec3(tex.rgba[i], tex.rgba[i + 1], tex.rgba[i + 2]);
        emissive *= glm::vec3(sum / double(tex.rgba.size() / 4));
        unsupported_.add("emissiveTexture (averaged to one colour)", name);
      }
    }
    out.emission = emissive;
    out.two_sided = m.doubleSided;

    // Normal map.
    if (const tinygltf::Image* img = texture_image(m.normalTexture.index, m.normalTexture.texCoord,
                                                   m.normalTexture.extensions, "normalTexture", name)) {
      out.normal_texture = colour_texture(img, /*srgb=*/false);
      out.normal_scale = finite_clamped(m.normalTexture.scale, 0.0f, 10.0f, 1.0f);
    }
    if (m.occlusionTexture.index >= 0) unsupported_.add("occlusionTexture (a path tracer computes occlusion)", name);

    // Alpha.
    if (m.alphaMode == "MASK") {
      const float cutoff = finite_clamped(m.alphaCutoff, 0.0f, 1.0f, 0.5f);
      out.alpha_texture = mask_texture(base_image, base[3], cutoff, name);
    } else if (m.alphaMode == "BLEND") {
      unsupported_.add("alphaMode BLEND (rendered opaque)", name);
    }
    for (const auto& [ext, value] : m.extensions)
      if (!handled_extension(ext)) unsupported_.add("material extension " + ext, name);
    return out;
  }

  // The cut-out texture of an alpha-masked material. The renderer cuts out where the
  // (bilinearly filtered) texture's alpha is below 0.5, so alpha = base factor x texel alpha
  // is remapped piecewise linearly to put the material's cutoff at 0.5.
  int mask_texture(const tinygltf::Image* img, float factor, float cutoff, const std::string& mat) {
    auto remap = [cutoff](float a) {
      if (cutoff <= 0.0f) return 1.0f;
      if (a < cutoff) return 0.5f * a / cutoff;
      return cutoff >= 1.0f ? 1.0f : 0.5f + 0.5f * (a - cutoff) / (1.0f - cutoff);
    };
    Texture tex;
    if (!img || !image_pixels(*img, /*srgb=*/false, tex)) {
      if (factor >= cutoff) return -1;  // nothing is cut out
      tex.width = tex.height = 1;
      tex.rgba.assign(4, 1.0f);
    }
    tex.path = path_ + " (alpha mask of material '" + mat + "')";
    for (std::size_t i = 0; i < tex.rgba.size(); i += 4) {
      const float a = remap(std::clamp(tex.rgba[i + 3] * factor, 0.0f, 1.0f));
      tex.rgba[i] = tex.rgba[i + 1] = tex.rgba[i + 2] = tex.rgba[i + 3] = a;
    }
    scene_.textures.push_back(std::move(tex));
    return int(scene_.textures.size()) - 1;
  }

  // --- nodes and meshes ----------------------------------------------------------------------

  // The node's rest transform as the file gives it: a matrix, or translation, rotation
  // (normalised) and scale.
  RigNode node_transform(const tinygltf::Node& n, const std::string& where) const {
    RigNode out;
    if (n.matrix.size() == 16) {
      out.has_matrix = true;
      for (int i = 0; i < 16; ++i) glm::value_ptr(out.matrix)[i] = n.matrix[std::size_t(i)];  // column-major, as glTF
      return out;
    }
    if (!n.matrix.empty()) read_.fail(where + ": matrix must have 16 numbers");
    if (n.translation.size() == 3) out.translation = glm::dvec3(n.translation[0], n.translation[1], n.translation[2]);
    else if (!n.translation.empty()) read_.fail(where + ": translation must have 3 numbers");
    if (n.scale.size() == 3) out.scale = glm::dvec3(n.scale[0], n.scale[1], n.scale[2]);
    else if (!n.scale.empty()) read_.fail(where + ": scale must have 3 numbers");
    if (n.rotation.size() == 4) {
      glm::dquat r(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);  // glTF stores x, y, z, w
      const double len = glm::length(r);
      if (!(len > 0.0) || !std::isfinite(len)) read_.fail(where + ": rotation is not a usable quaternion");
      out.rotation = r / len;
    } else if (!n.rotation.empty()) {
      read_.fail(where + ": rotation must have 4 numbers");
    }
    return out;
  }

  static glm::dmat4 local_matrix(const RigNode& n) {
    return n.has_matrix ? n.matrix : trs_matrix(n.translation, n.rotation, n.scale);
  }

  // Node chains are followed by recursion: bounded, so a file cannot overflow the stack.
  static constexpr int kMaxNodeDepth = 256;

  void visit(int index, const glm::dmat4& parent, int parent_index, const std::string& from, int depth) {
    if (index < 0 || std::size_t(index) >= model_.nodes.size())
      read_.fail(from + " names node " + std::to_string(index) + ", which does not exist");
    if (depth >= kMaxNodeDepth)
      read_.fail("node hierarchy deeper than " + std::to_string(kMaxNodeDepth) + " levels (at node " +
                 std::to_string(index) + ")");
    const std::string where = "node " + std::to_string(index);
    if (visited_[std::size_t(index)])
      read_.fail(where + " is reached twice in the node hierarchy (a cycle or a shared child)");
    visited_[std::size_t(index)] = 1;
    const tinygltf::Node& n = model_.nodes[std::size_t(index)];
    RigNode rest = node_transform(n, where);
    const glm::dmat4 world = parent * local_matrix(rest);
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r)
        if (!std::isfinite(world[c][r])) read_.fail(where + ": its transform is not finite");
    if (rig_) {
      rest.parent = parent_index;
      rig_->nodes[std::size_t(index)] = rest;
      rig_->order.push_back(index);
    }
    if (n.camera >= 0) camera(n.camera, world, where, index);
    if (n.mesh >= 0) mesh(n.mesh, world, where, index, n.skin);
    for (const auto& [ext, value] : n.extensions) {
      if (ext == "KHR_lights_punctual" && value.IsObject() && value.Has("light") && value.Get("light").IsInt())
        light(value.Get("light").GetNumberAsInt(), world, where);
      else
        unsupported_.add("node extension " + ext, where);
    }
    for (int c : n.children) visit(c, world, index, where, depth + 1);
  }

  void camera(int index, const glm::dmat4& world, const std::string& where, int node) {
    if (std::size_t(index) >= model_.cameras.size())
      read_.fail(where + " names camera " + std::to_string(index) + ", which does not exist");
    const tinygltf::Camera& c = model_.cameras[std::size_t(index)];
    if (c.type != "perspective") {
      unsupported_.add("orthographic cameras", where);
      return;
    }
    if (camera_found_) return;  // the first perspective camera is the view
    const double yfov = c.perspective.yfov;
    if (!(yfov > 0.0 && yfov < std::numbers::pi)) {
      scene_.stats.warnings.push_back(path_ + ": camera " + std::to_string(index) +
                                      " has an unusable yfov; framing the scene instead");
      return;
    }
    if (!camera_from_node(world, scene_.camera)) {
      scene_.stats.warnings.push_back(path_ + ": camera " + std::to_string(index) +
                                      " has a degenerate orientation; framing the scene instead");
      return;
    }
    scene_.camera.vfov_deg = float(glm::degrees(yfov));
    camera_found_ = true;
    if (rig_) rig_->camera_node = node;
  }

  // KHR_lights_punctual. The renderer's lights are emissive triangles, one sun and a sky: the
  // first directional light becomes the sun (its illuminance, lux, spread over the sun disk's
  // solid angle as radiance); point and spot lights have no counterpart and are named in the
  // warning line. The light's rest pose is used (an animated light does not move).
  void light(int index, const glm::dmat4& world, const std::string& where) {
    if (index < 0 || std::size_t(index) >= model_.lights.size())
      read_.fail(where + " names light " + std::to_string(index) + ", which does not exist");
    const tinygltf::Light& l = model_.lights[std::size_t(index)];
    if (l.type != "directional") {
      unsupported_.add("point and spot lights (KHR_lights_punctual)", where);
      return;
    }
    if (scene_.sun.enabled) {
      unsupported_.add("directional lights after the first (KHR_lights_punctual)", where);
      return;
    }
    const glm::dvec3 travel(world * glm::dvec4(0.0, 0.0, -1.0, 0.0));
    const double len = glm::length(travel);
    if (!(len > 0.0) || !std::isfinite(len)) {
      scene_.stats.warnings.push_back(path_ + ": " + where + ": directional light with a degenerate direction; ignored");
      return;
    }
    glm::vec3 colour(1.0f);
    for (std::size_t c = 0; c < 3 && c < l.color.size(); ++c) colour[int(c)] = finite_clamped(l.color[c], 0.0f, 1.0f, 1.0f);
    const float lux = std::isfinite(l.intensity) && l.intensity > 0.0 ? float(std::min(l.intensity, 1e9)) : 0.0f;
    Sun& sun = scene_.sun;
    sun.enabled = lux > 0.0f;
    sun.direction = glm::vec3(-travel / len);  // towards the light
    const double cos_max = std::cos(glm::radians(double(sun.angular_radius_deg)));
    sun.radiance = colour * float(lux / (2.0 * std::numbers::pi * (1.0 - cos_max)));
  }

  std::uint32_t default_material() {
    if (default_material_ < 0) {
      // A primitive without a material: the same grey as an OBJ face without one.
      Material grey;
      grey.name = "default";
      grey.diffuse = glm::vec3(0.7f);
      scene_.materials.push_back(grey);
      default_material_ = int(scene_.materials.size()) - 1;
    }
    return std::uint32_t(default_material_);
  }

  void mesh(int index, const glm::dmat4& world, const std::string& where, int node, int skin) {
    if (std::size_t(index) >= model_.meshes.size())
      read_.fail(where + " names mesh " + std::to_string(index) + ", which does not exist");
    if (skin >= 0 && std::size_t(skin) >= model_.skins.size())
      read_.fail(where + " names skin " + std::to_string(skin) + ", which does not exist");
    if (rig_) {
      // Posed later (pose_at_rest, and every frame): the primitives are read once per mesh,
      // whichever nodes share it.
      auto [it, fresh] = rig_meshes_.try_emplace(index);
      if (fresh)
        for (std::size_t pi = 0; pi < model_.meshes[std::size_t(index)].primitives.size(); ++pi)
          if (auto prim = primitive(index, pi)) {
            rig_->primitives.push_back(std::move(*prim));
            it->second.push_back(int(rig_->primitives.size()) - 1);
          }
      RigMeshInstance inst;
      inst.node = node;
      inst.skin = skin;
      inst.primitives = it->second;
      if (skin >= 0)
        for (int p : inst.primitives)
          if (rig_->primitives[std::size_t(p)].joints.empty())
            unsupported_.add("skins on primitives without JOINTS_0 and WEIGHTS_0 (rendered unskinned)", where);
      rig_->instances.push_back(std::move(inst));
      return;
    }
    // Placed once every node is visited (place_meshes): a mesh that several nodes draw may be
    // stored once, as instances.
    placements_.push_back({index, world});
  }

  // The primitives of mesh `index` in its own space (read once, whichever nodes draw it).
  const std::vector<RigPrimitive>& mesh_primitives(int index) {
    auto [it, fresh] = static_meshes_.try_emplace(index);
    if (fresh)
      for (std::size_t pi = 0; pi < model_.meshes[std::size_t(index)].primitives.size(); ++pi)
        if (auto prim = primitive(index, pi)) it->second.push_back(std::move(*prim));
    return it->second;
  }

  // Emits every mesh a node draws, in the order the nodes were visited. A mesh that two or more
  // nodes draw becomes instances (Scene::instancing: one copy in its own space, a matrix per
  // node), unless it emits light (the light table samples emitters by their world triangles)
  // or the options ask for flat copies. A node whose transform mirrors draws its own flat
  // copy (turning the winding round is done per triangle, as emit_primitive does).
  void place_meshes() {
    const bool instancing = options_.instancing;
    std::map<int, int> uses;
    for (const Placement& pl : placements_)
      if (glm::determinant(glm::dmat3(pl.world)) > 0.0) ++uses[pl.mesh];
    std::map<int, bool> instanced;
    for (const auto& [mesh, n] : uses) {
      bool ok = instancing && n >= 2;
      for (const RigPrimitive& prim : mesh_primitives(mesh))
        ok &= !scene_.materials.at(prim.material).is_emissive();
      instanced[mesh] = ok;
    }
    std::vector<std::array<glm::vec3, 3>>* colours = colours_out();
    const auto flat = [&](const Placement& pl) {
      const auto it = instanced.find(pl.mesh);
      return it == instanced.end() || !it->second || !(glm::determinant(glm::dmat3(pl.world)) > 0.0);
    };
    // A mesh's primitives are released after its last flat copy (unless it is instanced too), so
    // that a file of many meshes holds one at a time, as it did before placements were deferred.
    std::map<int, int> copies_left;
    for (const Placement& pl : placements_)
      if (flat(pl)) ++copies_left[pl.mesh];
    {
      // Room for every triangle at once: growing a 10M-triangle array by doubling had copied it
      // and touched twice its memory.
      std::size_t expected = scene_.triangles.size();
      std::set<int> stored;  // an instanced mesh is stored once
      for (const Placement& pl : placements_)
        if (flat(pl) || stored.insert(pl.mesh).second)
          for (const RigPrimitive& prim : mesh_primitives(pl.mesh)) expected += prim.triangles.size();
      scene_.triangles.reserve(expected);
    }
    // Every mesh a node draws is decoded now (the count above): the file's buffers are read no
    // more, and go before the triangles are made (the 10M heightfield's 172 MiB, at the load's
    // highest point).
    if (release_buffers_) release_buffers_();
    for (const Placement& pl : placements_) {
      if (!flat(pl)) continue;
      for (const RigPrimitive& prim : mesh_primitives(pl.mesh))
        emit_primitive(prim, pl.world, nullptr, nullptr, nullptr, scene_.triangles, scene_.stats, colours);
      if (--copies_left[pl.mesh] == 0 && !instanced[pl.mesh]) static_meshes_.erase(pl.mesh);
    }
    SceneInstancing in;
    in.world_triangles = scene_.triangles.size();
    std::map<int, std::uint32_t> mesh_slot;
    for (const Placement& pl : placements_) {
      if (flat(pl)) continue;
      auto [slot, fresh] = mesh_slot.try_emplace(pl.mesh, std::uint32_t(in.meshes.size()));
      if (fresh) {
        InstancedMesh m;
        m.first = scene_.triangles.size();
        for (const RigPrimitive& prim : mesh_primitives(pl.mesh))
          emit_primitive(prim, glm::dmat4(1.0), nullptr, nullptr, nullptr, scene_.triangles, scene_.stats, colours);
        m.count = scene_.triangles.size() - m.first;
        static_meshes_.erase(pl.mesh);  // stored: its primitives are no longer needed
        if (m.count == 0) {  // nothing drawable: no instances either
          slot->second = std::numeric_limits<std::uint32_t>::max();
        } else {
          in.meshes.push_back(m);
        }
      }
      if (slot->second == std::numeric_limits<std::uint32_t>::max()) continue;
      MeshInstance inst;
      inst.mesh = slot->second;
      inst.object_to_world = glm::mat4(pl.world);
      in.instances.push_back(inst);
    }
    if (!in.instances.empty()) scene_.instancing = std::move(in);
  }

  // Primitive `pi` of mesh `index` in its own space, or nothing (with a warning) when it is not
  // made of triangles.
  std::optional<RigPrimitive> primitive(int index, std::size_t pi) {
    const tinygltf::Primitive& prim = model_.meshes[std::size_t(index)].primitives[pi];
    const std::string what = "mesh " + std::to_string(index) + " primitive " + std::to_string(pi);
    if (!prim.targets.empty()) unsupported_.add("morph targets", "mesh " + std::to_string(index));
    for (const auto& [ext, value] : prim.extensions) unsupported_.add("primitive extension " + ext, what);
    const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN) {
      unsupported_.add(mode == TINYGLTF_MODE_POINTS ? "point primitives" : "line primitives", what);
      return std::nullopt;
    }
    RigPrimitive out;
    const auto pos_it = prim.attributes.find("POSITION");
    if (pos_it == prim.attributes.end()) read_.fail(what + " has no POSITION attribute");
    {
      const std::vector<glm::vec4> positions = read_.floats(pos_it->second, {TINYGLTF_TYPE_VEC3}, what + " POSITION", false);
      out.positions.resize(positions.size());
      for (std::size_t v = 0; v < positions.size(); ++v) out.positions[v] = glm::vec3(positions[v]);
    }
    const std::size_t nv = out.positions.size();
    if (auto it = prim.attributes.find("NORMAL"); it != prim.attributes.end()) {
      const auto normals = read_.floats(it->second, {TINYGLTF_TYPE_VEC3}, what + " NORMAL", false);
      if (normals.size() != nv) read_.fail(what + ": NORMAL and POSITION counts differ");
      out.normals.resize(nv);
      for (std::size_t v = 0; v < nv; ++v) out.normals[v] = glm::vec3(normals[v]);
    }
    if (auto it = prim.attributes.find("TEXCOORD_0"); it != prim.attributes.end()) {
      const auto uvs = read_.floats(it->second, {TINYGLTF_TYPE_VEC2}, what + " TEXCOORD_0", true);
      if (uvs.size() != nv) read_.fail(what + ": TEXCOORD_0 and POSITION counts differ");
      out.uvs.resize(nv);
      for (std::size_t v = 0; v < nv; ++v) out.uvs[v] = glm::vec2(uvs[v]);
    }
    const auto joints_it = prim.attributes.find("JOINTS_0"), weights_it = prim.attributes.find("WEIGHTS_0");
    if (rig_ && joints_it != prim.attributes.end() && weights_it != prim.attributes.end()) {
      out.joints = read_.floats(joints_it->second, {TINYGLTF_TYPE_VEC4}, what + " JOINTS_0", true);
      out.weights = read_.floats(weights_it->second, {TINYGLTF_TYPE_VEC4}, what + " WEIGHTS_0", true);
      if (out.joints.size() != nv || out.weights.size() != nv)
        read_.fail(what + ": JOINTS_0, WEIGHTS_0 and POSITION counts differ");
    }
    for (const auto& [attr, acc] : prim.attributes)
      if (attr.rfind("JOINTS_", 0) == 0 || attr.rfind("WEIGHTS_", 0) == 0) {
        if (attr != "JOINTS_0" && attr != "WEIGHTS_0") unsupported_.add("more than four joints per vertex", what);
        else if (!rig_) unsupported_.add("skins", what);
      } else if (attr.rfind("COLOR_", 0) == 0 && attr != "COLOR_0") {
        unsupported_.add("vertex colour sets other than COLOR_0", what);
      }
    if (auto it = prim.attributes.find("COLOR_0"); it != prim.attributes.end()) {
      // Linear RGB(A), floats or normalised integers; alpha is not rendered.
      const auto colours = read_.floats(it->second, {TINYGLTF_TYPE_VEC3, TINYGLTF_TYPE_VEC4}, what + " COLOR_0", true);
      if (colours.size() != nv) read_.fail(what + ": COLOR_0 and POSITION counts differ");
      out.colours.resize(nv);
      for (std::size_t v = 0; v < nv; ++v) {
        const glm::vec4& c = colours[v];
        for (int k = 0; k < 3; ++k) out.colours[v][k] = std::isfinite(c[k]) ? std::clamp(c[k], 0.0f, 1.0f) : 1.0f;
      }
    }

    std::vector<std::uint32_t> idx;
    if (prim.indices >= 0) {
      idx = read_.indices(prim.indices, what + " indices");
      for (std::size_t i = 0; i < idx.size(); ++i)
        if (idx[i] >= nv)
          read_.fail(what + ": index " + std::to_string(idx[i]) + " (at " + std::to_string(i) +
                     ") is out of range (" + std::to_string(nv) + " vertices)");
    } else {
      idx.resize(nv);
      for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = std::uint32_t(i);
    }
    auto& tris = out.triangles;
    if (mode == TINYGLTF_MODE_TRIANGLES) {
      for (std::size_t i = 0; i + 2 < idx.size(); i += 3) tris.push_back({idx[i], idx[i + 1], idx[i + 2]});
    } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      for (std::size_t i = 0; i + 2 < idx.size(); ++i)
        tris.push_back(i % 2 == 0 ? std::array{idx[i], idx[i + 1], idx[i + 2]}
                                  : std::array{idx[i + 1], idx[i], idx[i + 2]});
    } else {
      for (std::size_t i = 1; i + 1 < idx.size(); ++i) tris.push_back({idx[0], idx[i], idx[i + 1]});
    }

    if (prim.material >= 0 && std::size_t(prim.material) < model_.materials.size())
      out.material = std::uint32_t(prim.material);
    else {
      if (prim.material >= 0)
        scene_.stats.warnings.push_back(path_ + ": " + what + " names material " + std::to_string(prim.material) +
                                        ", which does not exist; using a default grey");
      out.material = default_material();
    }
    return out;
  }

  // --- skins and animations (a scene with a rig only) ---------------------------------------

  void skins() {
    for (std::size_t si = 0; si < model_.skins.size(); ++si) {
      const tinygltf::Skin& s = model_.skins[si];
      const std::string what = "skin " + std::to_string(si);
      RigSkin skin;
      for (int j : s.joints) {
        if (j < 0 || std::size_t(j) >= model_.nodes.size())
          read_.fail(what + " names joint node " + std::to_string(j) + ", which does not exist");
        skin.joints.push_back(j);
      }
      if (s.inverseBindMatrices >= 0) {
        skin.inverse_bind = read_.matrices(s.inverseBindMatrices, what + " inverseBindMatrices");
        if (skin.inverse_bind.size() < skin.joints.size())
          read_.fail(what + ": " + std::to_string(skin.inverse_bind.size()) + " inverse bind matrices for " +
                     std::to_string(skin.joints.size()) + " joints");
        skin.inverse_bind.resize(skin.joints.size());
      } else {
        skin.inverse_bind.assign(skin.joints.size(), glm::dmat4(1.0));
      }
      rig_->skins.push_back(std::move(skin));
    }
    // Every vertex's joints must name one of its skin's joints.
    for (const RigMeshInstance& inst : rig_->instances) {
      if (inst.skin < 0) continue;
      const std::size_t joints = rig_->skins[std::size_t(inst.skin)].joints.size();
      for (int p : inst.primitives)
        for (const glm::vec4& j : rig_->primitives[std::size_t(p)].joints)
          for (int k = 0; k < 4; ++k)
            if (!(j[k] >= 0.0f && std::size_t(j[k]) < joints))
              read_.fail("node " + std::to_string(inst.node) + ": a vertex names joint " + std::to_string(j[k]) +
                         " of skin " + std::to_string(inst.skin) + ", which has " + std::to_string(joints));
    }
  }

  void animations() {
    for (std::size_t ai = 0; ai < model_.animations.size(); ++ai) {
      const tinygltf::Animation& a = model_.animations[ai];
      const std::string what = "animation " + std::to_string(ai);
      AnimationClip clip;
      clip.name = a.name.empty() ? what : a.name;
      for (std::size_t ci = 0; ci < a.channels.size(); ++ci) {
        const tinygltf::AnimationChannel& c = a.channels[ci];
        const std::string where = what + " channel " + std::to_string(ci);
        if (c.target_node < 0) continue;  // glTF: a channel without a node is for an extension
        if (std::size_t(c.target_node) >= model_.nodes.size())
          read_.fail(where + " targets node " + std::to_string(c.target_node) + ", which does not exist");
        AnimationChannel ch;
        ch.node = c.target_node;
        if (c.target_path == "translation") ch.path = TrsPath::Translation;
        else if (c.target_path == "rotation") ch.path = TrsPath::Rotation;
        else if (c.target_path == "scale") ch.path = TrsPath::Scale;
        else {
          unsupported_.add(c.target_path == "weights" ? "morph target weights" : "animation path " + c.target_path, what);
          continue;
        }
        if (rig_->nodes[std::size_t(c.target_node)].has_matrix) {
          unsupported_.add("channels on nodes given by a matrix", where);
          continue;
        }
        if (c.sampler < 0 || std::size_t(c.sampler) >= a.samplers.size())
          read_.fail(where + " names sampler " + std::to_string(c.sampler) + ", which does not exist");
        const tinygltf::AnimationSampler& s = a.samplers[std::size_t(c.sampler)];
        KeyframeTrack& track = ch.track;
        if (s.interpolation.empty() || s.interpolation == "LINEAR") track.interpolation = Interpolation::Linear;
        else if (s.interpolation == "STEP") track.interpolation = Interpolation::Step;
        else if (s.interpolation == "CUBICSPLINE") track.interpolation = Interpolation::CubicSpline;
        else read_.fail(where + ": unknown interpolation '" + s.interpolation + "'");
        for (const glm::vec4& t : read_.floats(s.input, {TINYGLTF_TYPE_SCALAR}, where + " input", false)) {
          if (!std::isfinite(t.x) || (!track.times.empty() && !(t.x > track.times.back())))
            read_.fail(where + ": key times must be finite and strictly increasing");
          track.times.push_back(t.x);
        }
        const bool rotation = ch.path == TrsPath::Rotation;
        for (const glm::vec4& v : read_.floats(s.output, {rotation ? TINYGLTF_TYPE_VEC4 : TINYGLTF_TYPE_VEC3},
                                               where + " output", rotation)) {
          if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z) || !std::isfinite(v.w))
            read_.fail(where + ": output values must be finite");
          track.values.push_back(glm::dvec4(v));
        }
        const std::size_t per_key = track.interpolation == Interpolation::CubicSpline ? 3 : 1;
        if (track.times.empty() || track.values.size() != per_key * track.times.size())
          read_.fail(where + ": " + std::to_string(track.times.size()) + " key times for " +
                     std::to_string(track.values.size()) + " output values" +
                     (per_key == 3 ? " (CUBICSPLINE has three per key)" : ""));
        clip.duration = std::max(clip.duration, track.times.back());
        clip.channels.push_back(std::move(ch));
      }
      rig_->clips.push_back(std::move(clip));
    }
  }

  // The scene's triangles at the rest pose (the nodes' own transforms, skins bound by them):
  // the triangles kept here are the rig's for good. A scene without clips keeps no rig.
  void pose_at_rest() {
    // A rigid mesh on a node that a clip moves is drawn as an instance: its node's matrix places
    // it every frame, and its triangles are neither posed nor refitted; so is a still mesh that
    // several nodes draw. Not for skins, emitters (the light table samples world triangles), a
    // node that mirrors at rest, or when the options ask for flat copies.
    const bool instancing = options_.instancing && !rig_->clips.empty();
    if (instancing) {
      std::vector<int> all(rig_->clips.size());
      for (std::size_t c = 0; c < all.size(); ++c) all[c] = int(c);
      const std::vector<char> moves = moving_nodes(*rig_, all);
      const std::vector<glm::dmat4> world = rig_world_matrices(*rig_, 0.0, {});
      std::map<std::vector<int>, int> uses;  // rigid mesh instances per mesh (its primitives)
      for (const RigMeshInstance& inst : rig_->instances)
        if (inst.skin < 0) ++uses[inst.primitives];
      for (RigMeshInstance& inst : rig_->instances) {
        // Still meshes that other nodes draw too are stored once as well, as in a static file.
        bool ok = inst.skin < 0 && (moves[std::size_t(inst.node)] || uses[inst.primitives] >= 2) &&
                  glm::determinant(glm::dmat3(world[std::size_t(inst.node)])) > 0.0;
        for (int p : inst.primitives) ok &= !scene_.materials.at(rig_->primitives[std::size_t(p)].material).is_emissive();
        inst.instance = ok ? 0 : -1;  // numbered by settle_rig_instances
      }
    }
    settle_rig(*rig_, scene_.triangles, scene_.stats, colours_out());
    if (instancing) settle_rig_instances(*rig_, scene_.triangles, scene_.stats, colours_out(), scene_.instancing);
    if (!rig_->clips.empty()) scene_.rig = std::move(rig_);
    rig_.reset();
  }

  const tinygltf::Model& model_;
  std::string path_;
  SceneLoadOptions options_;
  Scene& scene_;
  Reader read_;
  Unsupported unsupported_;
  std::map<std::pair<const tinygltf::Image*, bool>, int> cache_;
  std::vector<char> visited_;
  // Scene::vertex_colours while any primitive of the file has COLOR_0, else null.
  std::vector<std::array<glm::vec3, 3>>* colours_out() {
    if (!any_colours_) {
      for (const tinygltf::Mesh& m : model_.meshes)
        for (const tinygltf::Primitive& p : m.primitives) any_colours_ |= p.attributes.count("COLOR_0") ? 1 : 0;
      any_colours_ |= 2;  // looked
    }
    return (any_colours_ & 1) ? &scene_.vertex_colours : nullptr;
  }
  int any_colours_ = 0;  // bit 0: the file has COLOR_0; bit 1: the file was looked at
  std::shared_ptr<SceneRig> rig_;           // while loading a scene that moves or is skinned
  std::map<int, std::vector<int>> rig_meshes_;  // glTF mesh -> its primitives in the rig
  // A static scene's meshes as the nodes place them (emitted by place_meshes), and each mesh's
  // primitives read once.
  struct Placement {
    int mesh;
    glm::dmat4 world;
  };
  std::vector<Placement> placements_;
  std::map<int, std::vector<RigPrimitive>> static_meshes_;
  int default_material_ = -1;
  bool camera_found_ = false;
};

}  // namespace

Scene load_gltf(const std::string& path, const SceneLoadOptions& options, bool* has_camera) {
  if (has_camera) *has_camera = false;
  std::string bytes = read_binary_file(path);
  const bool binary = bytes.size() >= 4 && read_u32(bytes, 0) == kGlbMagic;
  std::string json_text;
  if (binary) {
    if (bytes.size() < 20) throw SceneError(path + ": truncated GLB file (" + std::to_string(bytes.size()) + " bytes)");
    const std::uint32_t chunk_length = read_u32(bytes, 12), chunk_type = read_u32(bytes, 16);
    if (chunk_type != kGlbJsonChunk) throw SceneError(path + ": invalid GLB: the first chunk is not JSON");
    if (chunk_length > bytes.size() - 20)
      throw SceneError(path + ": invalid GLB: the JSON chunk reaches past the end of the file");
    json_text = bytes.substr(20, chunk_length);
  } else {
    json_text = bytes;
  }
  prescan_json(json_text, path);

  tinygltf::TinyGLTF loader;
  ImageLoadLog images;
  loader.SetImageLoader(&load_image_lenient, &images);
  tinygltf::Model model;
  std::string err, warn;
  const std::string base_dir = fs::absolute(fs::path(path)).parent_path().string();
  const bool ok =
      binary ? loader.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<const unsigned char*>(bytes.data()),
                                           unsigned(bytes.size()), base_dir)
             : loader.LoadASCIIFromString(&model, &err, &warn, bytes.data(), unsigned(bytes.size()), base_dir);
  // The model holds copies of the buffers: the file's bytes go before the triangles are made.
  std::string().swap(bytes);
  if (!ok) {
    const std::string why = one_line(err);
    throw SceneError(path + ": cannot load glTF: " + (why.empty() ? "unknown error" : why));
  }

  Scene scene;
  scene.name = fs::path(path).stem().string();
  // Required extensions change what the data means; without them the scene would be wrong.
  for (const std::string& e : model.extensionsRequired)
    if (!Converter::handled_extension(e))
      throw SceneError(path + ": requires glTF extension " + e + ", which parallax does not support");
  // tinygltf's warnings that matter (missing image files) are reported per material below.
  Converter convert(model, path, options, scene);
  convert.failed_images_ = images.failed;
  convert.release_buffers_ = [&model] {
    for (tinygltf::Buffer& b : model.buffers) std::vector<unsigned char>().swap(b.data);
  };
  convert.materials();
  convert.geometry(has_camera);
  convert.finish();

  if (scene.stats.dropped_degenerate > 0)
    scene.stats.warnings.push_back(path + ": dropped " + std::to_string(scene.stats.dropped_degenerate) +
                                   " degenerate (zero-area) triangles");
  if (scene.stats.dropped_nonfinite > 0)
    scene.stats.warnings.push_back(path + ": dropped " + std::to_string(scene.stats.dropped_nonfinite) +
                                   " triangles with non-finite coordinates");
  if (scene.triangles.empty())
    throw SceneError(path + ": no triangles (the default scene has no triangle meshes, or all were "
                            "degenerate or non-finite)");
  if (scene.materials.empty()) {
    Material grey;
    grey.name = "default";
    grey.diffuse = glm::vec3(0.7f);
    scene.materials.push_back(grey);
  }
  return scene;
}

}  // namespace px
