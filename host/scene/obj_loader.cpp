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
#include "scene/obj_materials.h"
#include "scene/obj_prescan.h"
#include "scene/primitives.h"
#include "scene/scene_file_bytes.h"
#include "scene/scene_loader.h"

#include <tiny_obj_loader.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <unordered_set>
#include <vector>

namespace px {

namespace fs = std::filesystem;
using obj::make_material;
using obj::MtlLibraryReader;
using obj::ObjPrescan;
using obj::prescan_obj;
using obj::TextureCache;

namespace {

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
  const bool parsed =
      tinyobj::LoadObj(&attrib, &shapes, &mtl_materials, &warn, &err, &stream, &mtl_reader, /*triangulate=*/false,
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
                                   " vertices with NaN, infinite or unreadable coordinates (line " + lines +
                                   (scan.bad_vertices > 3 ? ", ..." : "") + "); triangles using them are dropped");
  }
  if (scan.short_faces > 0) {
    scene.stats.warnings.push_back(path + ":" + std::to_string(scan.first_short_face_line) + ": " +
                                   std::to_string(scan.short_faces) + " faces with fewer than 3 vertices dropped");
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
      if (offset + count > mesh.indices.size()) throw SceneError(path + ": internal error: face index list truncated");
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
