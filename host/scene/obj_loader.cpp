// OBJ/MTL loading: tinyobjloader parses, this file validates, triangulates and converts.
//
// tinyobjloader is lenient in ways a renderer cannot afford: it reads "nan" as 0, accepts
// out-of-range indices with only a warning (and its polygon triangulation then reads past the
// vertex array), and reports the last line of the file for them. So before handing the text
// to it, a light pre-scan walks the file with the same line and token rules and
//   - refuses any face/line/point index that is zero or unparseable, and any vertex index out
//     of range, naming the line (after this, every vertex index tinyobjloader returns is known
//     to be valid); texture-coordinate and normal indices out of range only lose that
//     attribute, with a warning;
//   - parses vertex coordinates itself, so NaN/Inf (including MSVC's "1.#IND") are seen.
// tinyobjloader is then asked not to triangulate; polygons are ear-clipped here.
#include "image/image_io.h"
#include "scene/mtl_statements.h"
#include "scene/primitives.h"
#include "scene/scene_file_bytes.h"
#include "scene/scene_loader.h"

#include <tiny_obj_loader.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string_view>
#include <unordered_set>

namespace px {

namespace fs = std::filesystem;

namespace {

// ---------------------------------------------------------------------------------------------
// Line splitting with tinyobjloader's rules: "\n", "\r\n" and a lone "\r" end a
// line; a NUL ends its content (tinyobjloader parses through c_str()).


template <typename F>
void for_each_line(std::string_view text, F&& visit) {
  std::size_t line_no = 0, pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find_first_of("\r\n", pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(pos, end - pos);
    if (std::size_t nul = line.find('\0'); nul != std::string_view::npos) line = line.substr(0, nul);
    ++line_no;
    visit(line_no, line);
    pos = end;
    if (pos < text.size() && text[pos] == '\r') {
      ++pos;
      if (pos < text.size() && text[pos] == '\n') ++pos;
    } else if (pos < text.size()) {
      ++pos;  // '\n'
    }
  }
}

bool is_blank(char c) { return c == ' ' || c == '\t'; }

std::string_view skip_blanks(std::string_view s) {
  std::size_t i = 0;
  while (i < s.size() && is_blank(s[i])) ++i;
  return s.substr(i);
}

// Splits on blanks; empty fields are skipped.
std::vector<std::string_view> split_blanks(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && is_blank(s[i])) ++i;
    std::size_t j = i;
    while (j < s.size() && !is_blank(s[j])) ++j;
    if (j > i) out.push_back(s.substr(i, j - i));
    i = j;
  }
  return out;
}

// True when `line` starts with keyword `kw` followed by a blank (or end of line for keywords
// that may stand alone).
bool has_keyword(std::string_view line, std::string_view kw) {
  return line.size() > kw.size() && line.substr(0, kw.size()) == kw && is_blank(line[kw.size()]);
}

// A coordinate: a complete number token. Overflowing values become Inf (so they count as
// non-finite), underflowing ones are kept as the nearest float.
bool parse_coordinate(std::string_view tok, float& out) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  if (tok.empty()) return false;
  const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), out);
  if (r.ec == std::errc::result_out_of_range) {
    const std::string copy(tok);
    char* end = nullptr;
    out = float(std::strtod(copy.c_str(), &end));
    return end == copy.c_str() + copy.size();
  }
  return r.ec == std::errc() && r.ptr == tok.data() + tok.size();
}

bool parse_index(std::string_view tok, long long& out) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  if (tok.empty()) return false;
  const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), out);
  return r.ec == std::errc() && r.ptr == tok.data() + tok.size() &&
         out >= std::numeric_limits<int>::min() && out <= std::numeric_limits<int>::max();
}

// ---------------------------------------------------------------------------------------------
// Pre-scan.

struct ObjPrescan {
  std::vector<glm::vec3> positions;     // one per "v" line, NaN where unusable
  std::vector<std::size_t> bad_vertex_lines;  // first few lines with unusable coordinates
  std::size_t bad_vertices = 0;
  std::size_t short_faces = 0;          // faces with fewer than 3 corners
  std::size_t first_short_face_line = 0;
  std::size_t face_lines = 0, line_lines = 0, point_lines = 0;
  bool uses_materials = false;
  std::vector<std::string> warnings;
};

[[noreturn]] void fail_at(const std::string& path, std::size_t line, const std::string& what) {
  throw SceneError(path + ":" + std::to_string(line) + ": " + what);
}

ObjPrescan prescan_obj(std::string_view text, const std::string& path) {
  ObjPrescan scan;
  std::size_t nvt = 0, nvn = 0;
  // Positive indices may refer forwards (tinyobjloader resolves them against the final
  // counts), so those beyond the current count are kept, with their line, and checked once the
  // whole file is read (well-formed files have none).
  std::vector<std::pair<std::size_t, long long>> forward[3];
  const char* kind_name[3] = {"vertex", "texture coordinate", "normal"};
  // A texture coordinate or normal index out of range loses only that attribute: warn (first
  // line) and let the conversion fall back. A bad vertex index loses geometry: refuse.
  std::size_t missing_line[3] = {0, 0, 0};
  auto note_missing_attribute = [&](int kind, std::size_t line_no) {
    if (missing_line[kind] == 0 || line_no < missing_line[kind]) missing_line[kind] = line_no;
  };

  for_each_line(text, [&](std::size_t line_no, std::string_view raw) {
    const std::string_view line = skip_blanks(raw);
    if (line.empty() || line.front() == '#') return;
    if (has_keyword(line, "v")) {
      const auto toks = split_blanks(line.substr(2));
      glm::vec3 p(std::numeric_limits<float>::quiet_NaN());
      bool ok = toks.size() >= 3;
      for (int a = 0; ok && a < 3; ++a) ok = parse_coordinate(toks[a], p[a]) && std::isfinite(p[a]);
      if (!ok) {
        p = glm::vec3(std::numeric_limits<float>::quiet_NaN());
        if (scan.bad_vertices++ < 3) scan.bad_vertex_lines.push_back(line_no);
      }
      scan.positions.push_back(p);
      return;
    }
    if (has_keyword(line, "vt")) { ++nvt; return; }
    if (has_keyword(line, "vn")) { ++nvn; return; }
    if (line.substr(0, 6) == "usemtl") { scan.uses_materials = true; return; }
    const bool face = has_keyword(line, "f");
    if (!face && !has_keyword(line, "l") && !has_keyword(line, "p")) return;
    (face ? scan.face_lines : line.front() == 'l' ? scan.line_lines : scan.point_lines)++;

    const std::size_t counts[3] = {scan.positions.size(), nvt, nvn};
    const auto corners = split_blanks(line.substr(2));
    for (std::string_view corner : corners) {
      // i, i/j, i//k, i/j/k; a present field must be a non-zero integer.
      std::string_view fields[3];
      int nfields = 0;
      std::size_t start = 0;
      bool malformed = false;
      while (true) {
        const std::size_t slash = corner.find('/', start);
        if (nfields == 3) { malformed = true; break; }
        fields[nfields++] = corner.substr(start, slash == std::string_view::npos ? slash : slash - start);
        if (slash == std::string_view::npos) break;
        start = slash + 1;
      }
      // An empty field is only allowed for the texture coordinate of i//k.
      for (int f = 0; f < nfields && !malformed; ++f)
        if (fields[f].empty() && !(f == 1 && nfields == 3)) malformed = true;
      if (malformed) fail_at(path, line_no, "malformed index '" + std::string(corner) + "'");
      for (int f = 0; f < nfields; ++f) {
        if (fields[f].empty()) continue;
        long long idx = 0;
        if (!parse_index(fields[f], idx))
          fail_at(path, line_no, "invalid " + std::string(kind_name[f]) + " index '" +
                                     std::string(fields[f]) + "'");
        if (idx == 0)
          fail_at(path, line_no, std::string(kind_name[f]) + " index 0 is invalid (OBJ indices start at 1)");
        if (idx < 0 && -idx > static_cast<long long>(counts[f])) {
          if (f == 0)
            fail_at(path, line_no, "relative vertex index " + std::to_string(idx) +
                                       " is out of range (only " + std::to_string(counts[f]) +
                                       " defined so far)");
          note_missing_attribute(f, line_no);
        }
        if (idx > static_cast<long long>(counts[f])) forward[f].emplace_back(line_no, idx);
      }
    }
    if (face && corners.size() < 3) {
      if (scan.short_faces++ == 0) scan.first_short_face_line = line_no;
    }
  });

  const std::size_t final_counts[3] = {scan.positions.size(), nvt, nvn};
  for (int f = 0; f < 3; ++f)
    for (const auto& [line_no, idx] : forward[f]) {
      if (idx <= static_cast<long long>(final_counts[f])) continue;
      if (f == 0)
        fail_at(path, line_no, "vertex index " + std::to_string(idx) +
                                   " is out of range (the file defines " +
                                   std::to_string(final_counts[0]) + ")");
      note_missing_attribute(f, line_no);
      break;
    }
  for (int f = 1; f < 3; ++f)
    if (missing_line[f] > 0)
      scan.warnings.push_back(path + ":" + std::to_string(missing_line[f]) + ": " + kind_name[f] +
                              " indices refer to " + kind_name[f] + "s the file does not define; " +
                              (f == 1 ? "using (0, 0)" : "using geometric normals"));
  return scan;
}

// ---------------------------------------------------------------------------------------------
// Material libraries: looked up beside the OBJ, also under their bare file name (exporters
// often write a path from their own project root, e.g. "mtllib scenes/x.mtl" for a file that
// sits beside the OBJ) and with Windows separators turned around. The directory each material
// came from is kept: its texture paths are relative to it.

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

class MtlLibraryReader : public tinyobj::MaterialReader {
 public:
  MtlLibraryReader(fs::path obj_dir, std::string obj_path, std::vector<std::string>& warnings)
      : obj_dir_(std::move(obj_dir)), obj_path_(std::move(obj_path)), warnings_(warnings) {}

  bool operator()(const std::string& name, std::vector<tinyobj::material_t>* materials,
                  std::map<std::string, int>* material_map, std::string* warn,
                  std::string* err) override {
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

  // Where material `i` came from: the directory its textures are relative to, its library
  // file and the statements it wrote.
  struct Origin {
    fs::path directory;
    std::string library;
    MtlStatements statements;
  };
  Origin origin_of(std::size_t i) const {
    return i < origins_.size() ? origins_[i] : Origin{obj_dir_, obj_path_, {}};
  }

 private:
  fs::path obj_dir_;
  std::string obj_path_;
  std::vector<std::string>& warnings_;
  std::vector<Origin> origins_;
};

// ---------------------------------------------------------------------------------------------
// Textures.

float srgb_to_linear(float c) {
  c = std::clamp(c, 0.0f, 1.0f);
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

// kColour: map_Kd, map_Ks; kAlpha: map_d; kNormal: norm and bump (a direction per texel).
enum class TextureUse { kColour, kAlpha, kNormal };

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

class TextureCache {
 public:
  TextureCache(Scene& scene, std::string obj_path) : scene_(scene), obj_path_(std::move(obj_path)) {}

  // Returned by get() when `accept` turned the image down (no warning: the caller says why).
  static constexpr int kRejected = -2;

  // Index into scene.textures, or -1 (with a warning) when the file is missing or unreadable.
  // `what` (map_Kd, norm...) names the texture in warnings. `accept`, when given, decides from
  // the pixels whether the image is what the statement needs; a rejected image is not kept (a
  // bump height map would otherwise be uploaded for nothing).
  int get(const std::string& name, const std::vector<fs::path>& dirs, TextureUse use,
          const std::string& what, const std::string& material,
          bool (*accept)(const Texture&) = nullptr) {
    if (name.empty()) return -1;
    fs::path found;
    for (const fs::path& c : candidate_paths(dirs, name))
      if (is_file(c)) {
        found = c;
        break;
      }
    if (found.empty()) {
      scene_.stats.warnings.push_back(obj_path_ + ": material '" + material + "': " + what +
                                      " texture '" + name + "' not found; ignoring it");
      return -1;
    }
    const std::string key = std::to_string(int(use)) + (accept ? "?" : "") + "|" +
                            found.lexically_normal().string();
    if (auto it = index_.find(key); it != index_.end()) return it->second;
    Texture tex;
    tex.path = found.string();
    const std::string error = read_texture(found, use, tex);
    if (!error.empty()) {
      scene_.stats.warnings.push_back(obj_path_ + ": material '" + material + "': cannot read " +
                                      what + " texture '" + found.string() + "' (" + error +
                                      "); ignoring it");
      index_[key] = -1;
      return -1;
    }
    if (accept && !accept(tex)) return index_[key] = kRejected;
    scene_.textures.push_back(std::move(tex));
    return index_[key] = int(scene_.textures.size()) - 1;
  }

 private:
  Scene& scene_;
  std::string obj_path_;
  std::map<std::string, int> index_;
};

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
  out.diffuse = st.has("Kd") ? sane_colour(m.diffuse, 1.0f)
                : st.has("map_Kd") ? glm::vec3(1.0f) : glm::vec3(0.0f);
  out.specular = st.has("Ks") ? sane_colour(m.specular, 1.0f)
                 : st.has("map_Ks") ? glm::vec3(1.0f) : glm::vec3(0.0f);
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

// One MTL material with its textures; what it asks for but is not rendered goes to `ignored`.
Material make_material(const tinyobj::material_t& m, const MtlLibraryReader::Origin& origin,
                       const fs::path& obj_dir, TextureCache& textures, IgnoredMtlFeatures& ignored) {
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
    if (!is_modelled_mtl_keyword(kw) && !is_meaningless_in_path_tracer(kw))
      ignored.add(origin.library, kw, m.name);
  return mat;
}

// ---------------------------------------------------------------------------------------------
// Polygon triangulation: ear clipping in the plane of the polygon's Newell normal, keeping the
// polygon's winding. Falls back to a fan for polygons it cannot clip (self-intersecting) and
// for very large ones (ear clipping is quadratic).

using Tri = std::array<int, 3>;

void triangulate_polygon(const std::vector<glm::dvec3>& pts, std::vector<Tri>& out) {
  const int n = int(pts.size());
  out.clear();
  if (n < 3) return;
  if (n == 3) {
    out.push_back({0, 1, 2});
    return;
  }
  glm::dvec3 normal(0.0);
  for (int i = 0; i < n; ++i) {
    const glm::dvec3& a = pts[i];
    const glm::dvec3& b = pts[(i + 1) % n];
    normal += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
  }
  auto fan = [&] {
    for (int i = 1; i + 1 < n; ++i) out.push_back({0, i, i + 1});
  };
  const glm::dvec3 an = glm::abs(normal);
  if (!(an.x + an.y + an.z > 0.0) || n > 512) return fan();
  // Drop the dominant axis; flip one axis if needed so the polygon is counter-clockwise in 2D.
  const int drop = an.x >= an.y && an.x >= an.z ? 0 : an.y >= an.z ? 1 : 2;
  const int ax = (drop + 1) % 3, ay = (drop + 2) % 3;
  const double sign = normal[drop] >= 0.0 ? 1.0 : -1.0;
  std::vector<glm::dvec2> q(n);
  for (int i = 0; i < n; ++i) q[i] = glm::dvec2(pts[i][ax], sign * pts[i][ay]);
  auto cross2 = [](glm::dvec2 o, glm::dvec2 a, glm::dvec2 b) {
    return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
  };

  if (n == 4) {
    // Convex quad: split along the shorter diagonal (better-shaped triangles).
    bool convex = true;
    for (int i = 0; i < 4; ++i) convex &= cross2(q[i], q[(i + 1) % 4], q[(i + 2) % 4]) > 0.0;
    if (convex) {
      if (glm::length(pts[0] - pts[2]) <= glm::length(pts[1] - pts[3])) {
        out.push_back({0, 1, 2});
        out.push_back({0, 2, 3});
      } else {
        out.push_back({0, 1, 3});
        out.push_back({1, 2, 3});
      }
      return;
    }
  }

  std::vector<int> ring(n);
  for (int i = 0; i < n; ++i) ring[i] = i;
  // Only a reflex vertex can make a convex corner a non-ear, and one lying exactly on the
  // candidate's diagonal must block it too (an L shape's inner corner does), hence the
  // inclusive test.
  auto inside_or_on = [&](glm::dvec2 p, glm::dvec2 a, glm::dvec2 b, glm::dvec2 c) {
    return cross2(a, b, p) >= 0.0 && cross2(b, c, p) >= 0.0 && cross2(c, a, p) >= 0.0;
  };
  std::vector<char> reflex;
  while (ring.size() > 3) {
    const std::size_t m = ring.size();
    reflex.assign(m, 0);
    for (std::size_t k = 0; k < m; ++k)
      reflex[k] = cross2(q[ring[(k + m - 1) % m]], q[ring[k]], q[ring[(k + 1) % m]]) < 0.0;
    bool clipped = false;
    for (std::size_t i = 0; i < m && !clipped; ++i) {
      const int ia = ring[(i + m - 1) % m], ib = ring[i], ic = ring[(i + 1) % m];
      if (cross2(q[ia], q[ib], q[ic]) <= 0.0) continue;  // reflex or flat corner
      bool empty = true;
      for (std::size_t k = 0; k < m && empty; ++k) {
        if (!reflex[k]) continue;
        const int ip = ring[k];
        if (ip == ia || ip == ib || ip == ic) continue;
        if (q[ip] == q[ia] || q[ip] == q[ib] || q[ip] == q[ic]) continue;
        empty = !inside_or_on(q[ip], q[ia], q[ib], q[ic]);
      }
      if (!empty) continue;
      out.push_back({ia, ib, ic});
      ring.erase(ring.begin() + std::ptrdiff_t(i));
      clipped = true;
    }
    if (!clipped) {
      // No ear (self-intersecting or collinear remainder): fan the rest.
      for (std::size_t i = 1; i + 1 < ring.size(); ++i) out.push_back({ring[0], ring[i], ring[i + 1]});
      return;
    }
  }
  out.push_back({ring[0], ring[1], ring[2]});
}

// tinyobjloader's warnings, one per line, without the ones the pre-scan reports better.
void add_parser_warnings(const std::string& path, const std::string& warn, SceneStats& stats) {
  std::istringstream lines(warn);
  std::string line;
  std::unordered_set<std::string> seen;
  while (std::getline(lines, line)) {
    // The pre-scan reports these with the right line numbers.
    if (line.size() < 3 || line.find("Degenerated face") != std::string::npos ||
        line.find("out of bounds") != std::string::npos)
      continue;
    if (seen.insert(line).second) stats.warnings.push_back(path + ": " + line);
  }
}

glm::vec3 normalized_or(glm::vec3 n, glm::vec3 fallback) {
  const float len = glm::length(n);
  if (!(len > 0.0f) || !std::isfinite(len)) return fallback;
  return n / len;
}

}  // namespace

Scene load_obj(const std::string& path) {
  const std::string text = read_scene_file_bytes(path, "OBJ");
  const ObjPrescan scan = prescan_obj(text, path);

  Scene scene;
  scene.name = fs::path(path).stem().string();
  const fs::path obj_dir = fs::absolute(fs::path(path)).parent_path();

  tinyobj::attrib_t attrib;
  std::vector<tinyobj::shape_t> shapes;
  std::vector<tinyobj::material_t> mtl_materials;
  std::string warn, err;
  MtlLibraryReader mtl_reader(obj_dir, path, scene.stats.warnings);
  std::istringstream stream(text);
  const bool parsed = tinyobj::LoadObj(&attrib, &shapes, &mtl_materials, &warn, &err, &stream,
                                       &mtl_reader, /*triangulate=*/false,
                                       /*default_vcols_fallback=*/false);
  if (!parsed) {
    std::string first = err.substr(0, err.find('\n'));
    throw SceneError(path + ": cannot parse OBJ: " + (first.empty() ? "unknown error" : first));
  }
  add_parser_warnings(path, warn, scene.stats);
  for (const std::string& w : scan.warnings) scene.stats.warnings.push_back(w);
  if (attrib.vertices.size() != scan.positions.size() * 3)
    throw SceneError(path + ": internal error: vertex count mismatch between parsers");

  if (scan.bad_vertices > 0) {
    std::string lines;
    for (std::size_t l : scan.bad_vertex_lines) lines += (lines.empty() ? "" : ", ") + std::to_string(l);
    scene.stats.warnings.push_back(path + ": " + std::to_string(scan.bad_vertices) +
                                   " vertices with NaN, infinite or unreadable coordinates (line " +
                                   lines + (scan.bad_vertices > 3 ? ", ..." : "") +
                                   "); triangles using them are dropped");
  }
  if (scan.short_faces > 0) {
    scene.stats.warnings.push_back(path + ":" + std::to_string(scan.first_short_face_line) + ": " +
                                   std::to_string(scan.short_faces) +
                                   " faces with fewer than 3 vertices dropped");
    scene.stats.dropped_degenerate += scan.short_faces;
  }

  // Materials and their textures; what a material asks for but is not rendered is collected
  // and said in one line per library.
  TextureCache textures(scene, path);
  IgnoredMtlFeatures ignored;
  for (std::size_t i = 0; i < mtl_materials.size(); ++i) {
    const tinyobj::material_t& m = mtl_materials[i];
    scene.materials.push_back(make_material(m, mtl_reader.origin_of(i), obj_dir, textures, ignored));
  }
  for (std::string& line : ignored.warning_lines()) scene.stats.warnings.push_back(std::move(line));
  // Faces without a (known) material share one grey default, created on first use.
  int default_material = -1;
  auto material_for = [&](int id) -> std::uint32_t {
    if (id >= 0 && std::size_t(id) < mtl_materials.size()) return std::uint32_t(id);
    if (default_material < 0) {
      Material grey;
      grey.name = "default";
      grey.diffuse = glm::vec3(0.7f);
      scene.materials.push_back(grey);
      default_material = int(scene.materials.size()) - 1;
    }
    return std::uint32_t(default_material);
  };

  const std::size_t nv = scan.positions.size();
  const std::size_t nvn = attrib.normals.size() / 3;
  const std::size_t nvt = attrib.texcoords.size() / 2;
  std::vector<glm::dvec3> poly;
  std::vector<Tri> tris;
  std::size_t faces_without_material = 0;
  for (const tinyobj::shape_t& shape : shapes) {
    const tinyobj::mesh_t& mesh = shape.mesh;
    std::size_t offset = 0;
    for (std::size_t f = 0; f < mesh.num_face_vertices.size(); ++f) {
      const std::size_t count = mesh.num_face_vertices[f];
      if (offset + count > mesh.indices.size())
        throw SceneError(path + ": internal error: face index list truncated");
      const tinyobj::index_t* idx = &mesh.indices[offset];
      offset += count;
      // The pre-scan guarantees valid indices; checked again so no input can read out of bounds.
      for (std::size_t k = 0; k < count; ++k)
        if (idx[k].vertex_index < 0 || std::size_t(idx[k].vertex_index) >= nv)
          throw SceneError(path + ": vertex index out of range");
      if (count < 3) continue;  // counted by the pre-scan
      const int mat_id = f < mesh.material_ids.size() ? mesh.material_ids[f] : -1;
      if (mat_id < 0 || std::size_t(mat_id) >= mtl_materials.size()) ++faces_without_material;
      const std::uint32_t material = material_for(mat_id);

      poly.resize(count);
      bool finite = true;
      for (std::size_t k = 0; k < count; ++k) {
        const glm::vec3 p = scan.positions[std::size_t(idx[k].vertex_index)];
        finite &= std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
        poly[k] = glm::dvec3(p);
      }
      if (!finite) {
        scene.stats.dropped_nonfinite += count - 2;
        continue;
      }
      triangulate_polygon(poly, tris);
      for (const Tri& t : tris) {
        SceneTriangle tri;
        for (int c = 0; c < 3; ++c) tri.p[c] = scan.positions[std::size_t(idx[t[c]].vertex_index)];
        tri.material = material;
        if (is_degenerate(tri)) {
          ++scene.stats.dropped_degenerate;
          continue;
        }
        const glm::vec3 ng = geometric_normal(tri);
        if (ng == glm::vec3(0.0f)) {  // area overflowed: not representable
          ++scene.stats.dropped_nonfinite;
          continue;
        }
        for (int c = 0; c < 3; ++c) {
          const tinyobj::index_t& ix = idx[t[c]];
          glm::vec3 n = ng;
          if (ix.normal_index >= 0 && std::size_t(ix.normal_index) < nvn) {
            const float* a = &attrib.normals[3 * std::size_t(ix.normal_index)];
            n = normalized_or(glm::vec3(a[0], a[1], a[2]), ng);
          }
          tri.n[c] = n;
          glm::vec2 uv(0.0f);
          if (ix.texcoord_index >= 0 && std::size_t(ix.texcoord_index) < nvt) {
            const float* a = &attrib.texcoords[2 * std::size_t(ix.texcoord_index)];
            if (std::isfinite(a[0]) && std::isfinite(a[1])) uv = glm::vec2(a[0], a[1]);
          }
          tri.uv[c] = uv;
        }
        scene.triangles.push_back(tri);
      }
    }
  }

  if (scan.uses_materials && faces_without_material > 0)
    scene.stats.warnings.push_back(path + ": " + std::to_string(faces_without_material) +
                                   " faces have no known material; using a default grey");
  if (scene.stats.dropped_degenerate > 0)
    scene.stats.warnings.push_back(path + ": dropped " + std::to_string(scene.stats.dropped_degenerate) +
                                   " degenerate (zero-area) triangles");
  if (scene.stats.dropped_nonfinite > 0)
    scene.stats.warnings.push_back(path + ": dropped " + std::to_string(scene.stats.dropped_nonfinite) +
                                   " triangles with non-finite coordinates");

  if (scene.triangles.empty()) {
    std::string why;
    if (scan.face_lines == 0 && (scan.line_lines > 0 || scan.point_lines > 0))
      why = " (the file has only lines/points)";
    else if (scan.face_lines == 0)
      why = " (the file has no faces)";
    else
      why = " (all faces were degenerate or non-finite)";
    throw SceneError(path + ": no triangles" + why);
  }
  if (scene.materials.empty()) material_for(-1);
  return scene;
}

}  // namespace px
