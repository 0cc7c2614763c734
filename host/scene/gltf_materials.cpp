// glTF materials and their textures onto the renderer's model (the mapping is listed in
// gltf_loader.cpp).
#include "scene/gltf_converter.h"

#include <cmath>

namespace px::gltf {

namespace {

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

}  // namespace

void Converter::materials() {
  for (std::size_t i = 0; i < model_.materials.size(); ++i) scene_.materials.push_back(material(i));
}

double Converter::number_in(const tinygltf::ExtensionMap& ext, const std::string& name, const std::string& key,
                            double fallback) {
  const auto it = ext.find(name);
  if (it == ext.end() || !it->second.IsObject() || !it->second.Has(key)) return fallback;
  const tinygltf::Value& v = it->second.Get(key);
  return v.IsNumber() || v.IsInt() ? v.GetNumberAsDouble() : fallback;
}

float Converter::finite_clamped(double v, float lo, float hi, float fallback) {
  return std::isfinite(v) ? std::clamp(float(v), lo, hi) : fallback;
}

const tinygltf::Image* Converter::texture_image(const tinygltf::TextureInfo& info, const std::string& what,
                                                const std::string& mat) {
  return texture_image(info.index, info.texCoord, info.extensions, what, mat);
}

const tinygltf::Image* Converter::texture_image(int index, int tex_coord, const tinygltf::ExtensionMap& ext,
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
    scene_.stats.warnings.push_back(path_ + ": material '" + mat + "': " + what + " texture " + std::to_string(index) +
                                    " has no image; ignoring it");
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

int Converter::colour_texture(const tinygltf::Image* img, bool srgb) {
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

Material Converter::material(std::size_t index) {
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
      for (std::size_t i = 0; i < tex.rgba.size(); i += 4)
        sum += glm::dvec3(tex.rgba[i], tex.rgba[i + 1], tex.rgba[i + 2]);
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

int Converter::mask_texture(const tinygltf::Image* img, float factor, float cutoff, const std::string& mat) {
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

}  // namespace px::gltf
