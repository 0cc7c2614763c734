// OBJ materials: material libraries, textures and MTL -> Material (obj_materials.h).
#include "scene/obj_materials.h"

#include "image/image_io.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

namespace px::obj {

namespace {

std::vector<fs::path> candidate_paths(const std::vector<fs::path>& dirs, const std::string& name) {
  std::string slashed = name;
  std::replace(slashed.begin(), slashed.end(), '\\', '/');
  std::vector<fs::path> out;
  auto add = [&](const fs::path& p) {
    if (std::find(out.begin(), out.end(), p) == out.end()) out.push_back(p);
  };
  if (fs::path(slashed).is_absolute()) add(fs::path(slashed));
  for (const fs::path& d : dirs) {
    add(d / name);
    add(d / slashed);
  }
  for (const fs::path& d : dirs) add(d / fs::path(slashed).filename());
  return out;
}

bool is_file(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

// ---------------------------------------------------------------------------------------------
// Textures.

float srgb_to_linear(float c) {
  c = std::clamp(c, 0.0f, 1.0f);
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

// Loads an image into `tex`; on failure returns the reason. Colour textures in an integer
// format are sRGB-encoded (what 8-bit colour files hold) unless the file says it is linear;
// alpha and normal maps stay linear (they hold numbers, not colours). An alpha texture keeps
// its cut-out value in every channel, so the renderer reads .w whatever texture it is given
// (the alpha channel when the image has one, else the first channel).
std::string read_texture(const fs::path& file, TextureUse use, Texture& tex) {
  DecodedImage decoded;
  if (std::string error = decode_image_file(file.string(), decoded); !error.empty()) return error;
  const int w = decoded.width, h = decoded.height, nc = decoded.channels;
  const std::vector<float>& pixels = decoded.pixels;
  const bool srgb = use == TextureUse::kColour && decoded.integer_format && !decoded.tagged_linear;
  const int alpha_channel = decoded.alpha_channel >= 0 ? decoded.alpha_channel : nc == 2 || nc == 4 ? nc - 1 : -1;
  tex.width = w;
  tex.height = h;
  tex.rgba.resize(std::size_t(w) * h * 4);
  for (std::size_t i = 0, n = std::size_t(w) * h; i < n; ++i) {
    const float* px = &pixels[i * nc];
    float* out = &tex.rgba[i * 4];
    auto finite01 = [](float v) { return std::isfinite(v) ? std::max(v, 0.0f) : 0.0f; };
    if (use == TextureUse::kAlpha) {
      const float a = std::clamp(finite01(px[alpha_channel >= 0 ? alpha_channel : 0]), 0.0f, 1.0f);
      out[0] = out[1] = out[2] = out[3] = a;
      continue;
    }
    const bool grey = nc < 3;
    for (int c = 0; c < 3; ++c) {
      const float v = finite01(px[grey ? 0 : c]);
      out[c] = srgb ? srgb_to_linear(v) : v;
    }
    out[3] = alpha_channel >= 0 ? std::clamp(finite01(px[alpha_channel]), 0.0f, 1.0f) : 1.0f;
  }
  return {};
}

// ---------------------------------------------------------------------------------------------
// MTL -> Material.

glm::vec3 sane_colour(const tinyobj::real_t (&c)[3], float max_value) {
  glm::vec3 v(c[0], c[1], c[2]);
  for (int i = 0; i < 3; ++i) v[i] = std::isfinite(v[i]) ? std::clamp(v[i], 0.0f, max_value) : 0.0f;
  return v;
}

// MTL writes `bump` for both height maps and normal maps. A normal map is a colour image whose
// texels decode to directions around +z: blue well above one half on average, and not grey (a
// height map has r = g = b, or a single channel).
bool is_normal_map(const Texture& tex) {
  const std::size_t n = tex.rgba.size() / 4;
  if (n == 0) return false;
  double z = 0.0, chroma = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const float* t = &tex.rgba[4 * i];
    z += 2.0 * t[2] - 1.0;
    chroma += std::abs(t[0] - t[2]) + std::abs(t[1] - t[2]);
  }
  return z / double(n) > 0.5 && chroma / double(n) > 0.05;
}

// Glass, in MTL's words: an illumination model with refraction (4: glass, 6 and 7: refraction;
// 5 is Fresnel reflection without transparency and stays a mirror), a dissolve below 1 (d, or
// Tr = 1 - d), or a transmission filter that lets some light through but not all of it (Tf;
// exporters write "Tf 1 1 1" on every opaque material). Ni alone is no sign: exporters write it
// everywhere.
bool is_glass(const tinyobj::material_t& m, const MtlStatements& st) {
  if (m.illum == 4 || m.illum == 6 || m.illum == 7) return true;
  // A dissolve of 0 would be an invisible object; files that say so mostly come from exporters
  // that write Tr with the meaning of d (tinyobjloader's note on 3ds Max): left opaque, and
  // named in the ignored-features line.
  if (std::isfinite(m.dissolve) && m.dissolve > 0.0f && m.dissolve < 1.0f) return true;
  if (!st.has("Tf")) return false;
  const glm::vec3 tf = sane_colour(m.transmittance, 1.0f);
  const float hi = std::max(tf.x, std::max(tf.y, tf.z));
  return hi > 0.0f && tf != glm::vec3(1.0f);
}

Material convert_material(const tinyobj::material_t& m, const MtlStatements& st) {
  Material out;
  out.name = m.name;
  // Albedo above 1 would create energy; emission is radiance and unbounded. A colour map
  // without its colour statement is the texture's own colour (what OBJ viewers show): only an
  // explicit Kd / Ks scales it.
  out.diffuse = st.has("Kd") ? sane_colour(m.diffuse, 1.0f) : st.has("map_Kd") ? glm::vec3(1.0f) : glm::vec3(0.0f);
  out.specular = st.has("Ks") ? sane_colour(m.specular, 1.0f) : st.has("map_Ks") ? glm::vec3(1.0f) : glm::vec3(0.0f);
  out.emission = sane_colour(m.emission, std::numeric_limits<float>::max());
  // Phong exponent -> GGX alpha with the usual Beckmann-equivalent match (Walter et al. 2007).
  const float ns = std::isfinite(m.shininess) ? std::max(m.shininess, 0.0f) : 0.0f;
  out.roughness = std::sqrt(2.0f / (ns + 2.0f));
  if (is_glass(m, st)) {
    out.dielectric = true;
    // Without Ni (or with an unusable one), the index of common glass.
    const bool ni_usable = st.has("Ni") && std::isfinite(m.ior) && m.ior > 0.0f && m.ior <= 10.0f;
    out.ior = ni_usable ? m.ior : 1.5f;
    const glm::vec3 tf = sane_colour(m.transmittance, 1.0f);
    out.transmission = st.has("Tf") && std::max(tf.x, std::max(tf.y, tf.z)) > 0.0f ? tf : glm::vec3(1.0f);
    return out;
  }
  const bool has_specular = out.specular.x > 0.0f || out.specular.y > 0.0f || out.specular.z > 0.0f;
  const bool mirror_illum = m.illum == 3 || m.illum == 5;
  if (has_specular && (ns >= 1000.0f || mirror_illum)) {
    out.mirror = true;
    out.roughness = 0.0f;
  }
  return out;
}

// Texture options the loader does not apply (scale, offset): the map would land elsewhere.
bool has_unapplied_texture_options(const tinyobj::texture_option_t& o) {
  for (int i = 0; i < 3; ++i)
    if (o.origin_offset[i] != 0.0f || o.scale[i] != 1.0f || o.turbulence[i] != 0.0f) return true;
  return false;
}

}  // namespace

bool MtlLibraryReader::operator()(const std::string& name, std::vector<tinyobj::material_t>* materials,
                                  std::map<std::string, int>* material_map, std::string* warn, std::string* err) {
  for (const fs::path& candidate : candidate_paths({obj_dir_}, name)) {
    if (!is_file(candidate)) continue;
    std::ifstream file(candidate, std::ios::binary);
    if (!file) continue;
    std::ostringstream text;
    text << file.rdbuf();
    const std::vector<MtlStatements> statements = scan_mtl_statements(text.str());
    std::istringstream in(std::move(text).str());
    const std::size_t before = materials->size();
    tinyobj::LoadMtl(material_map, materials, &in, warn, err);
    origins_.resize(materials->size(), Origin{obj_dir_, obj_path_, {}});
    for (std::size_t i = before; i < materials->size(); ++i) {
      Origin& o = origins_[i];
      o.directory = candidate.parent_path();
      o.library = candidate.string();
      // Both readers create materials in file order; match by name should they disagree.
      const std::size_t k = i - before;
      const std::string& mname = (*materials)[i].name;
      if (k < statements.size() && statements[k].material == mname) {
        o.statements = statements[k];
      } else {
        for (const MtlStatements& st : statements)
          if (st.material == mname) o.statements = st;
      }
    }
    return true;
  }
  warnings_.push_back(obj_path_ + ": material library '" + name + "' not found beside the OBJ");
  return false;
}

int TextureCache::get(const std::string& name, const std::vector<fs::path>& dirs, TextureUse use,
                      const std::string& what, const std::string& material, bool (*accept)(const Texture&)) {
  if (name.empty()) return -1;
  fs::path found;
  for (const fs::path& c : candidate_paths(dirs, name))
    if (is_file(c)) {
      found = c;
      break;
    }
  if (found.empty()) {
    scene_.stats.warnings.push_back(obj_path_ + ": material '" + material + "': " + what + " texture '" + name +
                                    "' not found; ignoring it");
    return -1;
  }
  const std::string key = std::to_string(int(use)) + (accept ? "?" : "") + "|" + found.lexically_normal().string();
  if (auto it = index_.find(key); it != index_.end()) return it->second;
  Texture tex;
  tex.path = found.string();
  const std::string error = read_texture(found, use, tex);
  if (!error.empty()) {
    scene_.stats.warnings.push_back(obj_path_ + ": material '" + material + "': cannot read " + what + " texture '" +
                                    found.string() + "' (" + error + "); ignoring it");
    index_[key] = -1;
    return -1;
  }
  if (accept && !accept(tex)) return index_[key] = kRejected;
  scene_.textures.push_back(std::move(tex));
  return index_[key] = int(scene_.textures.size()) - 1;
}

// One MTL material with its textures; what it asks for but is not rendered goes to `ignored`.
Material make_material(const tinyobj::material_t& m, const MtlLibraryReader::Origin& origin, const fs::path& obj_dir,
                       TextureCache& textures, IgnoredMtlFeatures& ignored) {
  const MtlStatements& st = origin.statements;
  Material mat = convert_material(m, st);
  const std::vector<fs::path> dirs = {origin.directory, obj_dir};
  mat.diffuse_texture = textures.get(m.diffuse_texname, dirs, TextureUse::kColour, "map_Kd", m.name);
  if (mat.diffuse_texture < 0 && !st.has("Kd") && st.has("map_Kd"))
    mat.diffuse = Material{}.diffuse;  // texture unreadable (warned): neutral grey, not white
  mat.specular_texture = textures.get(m.specular_texname, dirs, TextureUse::kColour, "map_Ks", m.name);
  mat.alpha_texture = textures.get(m.alpha_texname, dirs, TextureUse::kAlpha, "map_d", m.name);
  // A normal map: `norm`, else a `bump` whose image holds normals (not heights).
  auto strength = [](const tinyobj::texture_option_t& o) {
    return std::isfinite(o.bump_multiplier) ? std::clamp(float(o.bump_multiplier), 0.0f, 10.0f) : 1.0f;
  };
  mat.normal_texture = textures.get(m.normal_texname, dirs, TextureUse::kNormal, "norm", m.name);
  mat.normal_scale = strength(m.normal_texopt);
  if (mat.normal_texture < 0 && !m.bump_texname.empty()) {
    const int bump = textures.get(m.bump_texname, dirs, TextureUse::kNormal, "bump", m.name, is_normal_map);
    if (bump == TextureCache::kRejected) ignored.add(origin.library, "bump height map", m.name);
    mat.normal_texture = std::max(bump, -1);
    mat.normal_scale = strength(m.bump_texopt);
  } else if (mat.normal_texture >= 0 && !m.bump_texname.empty() && m.bump_texname != m.normal_texname) {
    ignored.add(origin.library, "bump beside norm", m.name);
  }
  if (!(m.dissolve > 0.0f) && (st.has("d") || st.has("Tr")))
    ignored.add(origin.library, "fully transparent d 0 / Tr 1 (rendered opaque)", m.name);
  if (mat.dielectric && (mat.diffuse_texture >= 0 || mat.specular_texture >= 0))
    ignored.add(origin.library, "textures on glass", m.name);
  for (const auto* o : {&m.diffuse_texopt, &m.specular_texopt, &m.normal_texopt, &m.bump_texopt, &m.alpha_texopt})
    if (has_unapplied_texture_options(*o)) {
      ignored.add(origin.library, "texture options -o/-s/-t", m.name);
      break;
    }
  for (const std::string& kw : st.keywords)
    if (!is_modelled_mtl_keyword(kw) && !is_meaningless_in_path_tracer(kw)) ignored.add(origin.library, kw, m.name);
  return mat;
}

}  // namespace px::obj
