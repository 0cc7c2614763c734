#include "scene/primitives.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <unordered_map>

namespace px {

namespace {

glm::dvec3 to_double(glm::vec3 v) { return glm::dvec3(v); }

glm::dvec3 double_cross(const SceneTriangle& tri) {
  const glm::dvec3 p0 = to_double(tri.p[0]);
  return glm::cross(to_double(tri.p[1]) - p0, to_double(tri.p[2]) - p0);
}

// Appends a triangle with the given per-vertex normals; silently skips a zero-area one so that
// callers with degenerate input (a quad with a repeated corner) never emit it.
void emit(std::vector<SceneTriangle>& tris, glm::vec3 p0, glm::vec3 p1, glm::vec3 p2, glm::vec3 n0, glm::vec3 n1,
          glm::vec3 n2, glm::vec2 t0, glm::vec2 t1, glm::vec2 t2, std::uint32_t material) {
  SceneTriangle tri;
  tri.p[0] = p0;
  tri.p[1] = p1;
  tri.p[2] = p2;
  tri.n[0] = n0;
  tri.n[1] = n1;
  tri.n[2] = n2;
  tri.uv[0] = t0;
  tri.uv[1] = t1;
  tri.uv[2] = t2;
  tri.material = material;
  if (is_degenerate(tri)) return;
  tris.push_back(tri);
}

glm::vec3 safe_normalize(glm::dvec3 v) {
  const double len = glm::length(v);
  if (!(len > 0.0) || !std::isfinite(len)) return glm::vec3(0.0f);
  return glm::vec3(v / len);
}

}  // namespace

glm::vec3 geometric_normal(const SceneTriangle& tri) { return safe_normalize(double_cross(tri)); }

double triangle_area(const SceneTriangle& tri) { return 0.5 * glm::length(double_cross(tri)); }

bool has_finite_positions(const SceneTriangle& tri) {
  for (const glm::vec3& p : tri.p)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) return false;
  return true;
}

bool is_degenerate(const SceneTriangle& tri) {
  const glm::dvec3 c = double_cross(tri);
  // Written so that a finite zero cross product is degenerate and NaN is not (NaN is the
  // non-finite case, reported separately).
  return c.x == 0.0 && c.y == 0.0 && c.z == 0.0;
}

bool normal_unless_degenerate(const SceneTriangle& tri, glm::vec3* normal) {
  const glm::dvec3 c = double_cross(tri);
  if (c.x == 0.0 && c.y == 0.0 && c.z == 0.0) return false;  // as is_degenerate
  *normal = safe_normalize(c);
  return true;
}

void append_triangle(std::vector<SceneTriangle>& tris, glm::vec3 p0, glm::vec3 p1, glm::vec3 p2,
                     std::uint32_t material) {
  const glm::vec3 n = safe_normalize(glm::cross(to_double(p1) - to_double(p0), to_double(p2) - to_double(p0)));
  emit(tris, p0, p1, p2, n, n, n, {0, 0}, {1, 0}, {0, 1}, material);
}

void append_quad(std::vector<SceneTriangle>& tris, glm::vec3 p0, glm::vec3 p1, glm::vec3 p2, glm::vec3 p3,
                 std::uint32_t material, const QuadUv& uv) {
  // The cross product of the diagonals is the quad's area normal even when one of its two
  // triangles is degenerate, so both halves shade alike.
  const glm::vec3 n = safe_normalize(glm::cross(to_double(p2) - to_double(p0), to_double(p3) - to_double(p1)));
  emit(tris, p0, p1, p2, n, n, n, uv[0], uv[1], uv[2], material);
  emit(tris, p0, p2, p3, n, n, n, uv[0], uv[2], uv[3], material);
}

void append_quad_facing(std::vector<SceneTriangle>& tris, glm::vec3 p0, glm::vec3 p1, glm::vec3 p2, glm::vec3 p3,
                        glm::vec3 facing, std::uint32_t material, const QuadUv& uv) {
  const glm::dvec3 area_normal = glm::cross(to_double(p2) - to_double(p0), to_double(p3) - to_double(p1));
  if (glm::dot(area_normal, glm::dvec3(facing)) >= 0.0)
    append_quad(tris, p0, p1, p2, p3, material, uv);
  else
    append_quad(tris, p3, p2, p1, p0, material, {uv[3], uv[2], uv[1], uv[0]});
}

namespace {

// The six faces of a box as corner indices (bit 0 = x, bit 1 = y, bit 2 = z set means max),
// counter-clockwise seen from outside.
constexpr int kBoxFaces[6][4] = {
    {0, 4, 6, 2},  // -x
    {1, 3, 7, 5},  // +x
    {0, 1, 5, 4},  // -y
    {2, 6, 7, 3},  // +y
    {0, 2, 3, 1},  // -z
    {4, 5, 7, 6},  // +z
};

void append_box_corners(std::vector<SceneTriangle>& tris, const glm::vec3 (&c)[8], bool mirrored,
                        std::uint32_t material) {
  for (const auto& f : kBoxFaces) {
    if (mirrored)
      append_quad(tris, c[f[0]], c[f[3]], c[f[2]], c[f[1]], material);
    else
      append_quad(tris, c[f[0]], c[f[1]], c[f[2]], c[f[3]], material);
  }
}

}  // namespace

void append_box(std::vector<SceneTriangle>& tris, glm::vec3 min, glm::vec3 max, std::uint32_t material) {
  glm::vec3 c[8];
  for (int i = 0; i < 8; ++i)
    c[i] = glm::vec3((i & 1) ? max.x : min.x, (i & 2) ? max.y : min.y, (i & 4) ? max.z : min.z);
  append_box_corners(tris, c, false, material);
}

void append_oriented_box(std::vector<SceneTriangle>& tris, glm::vec3 min, glm::vec3 max, const glm::mat4& transform,
                         std::uint32_t material) {
  glm::vec3 c[8];
  for (int i = 0; i < 8; ++i) {
    const glm::vec4 local((i & 1) ? max.x : min.x, (i & 2) ? max.y : min.y, (i & 4) ? max.z : min.z, 1.0f);
    c[i] = glm::vec3(transform * local);
  }
  // A mirroring transform turns counter-clockwise into clockwise; reverse to stay outward.
  const bool mirrored = glm::determinant(glm::mat3(transform)) < 0.0f;
  append_box_corners(tris, c, mirrored, material);
}

void append_slivers(std::vector<SceneTriangle>& tris, std::size_t n, unsigned seed, std::uint32_t material) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  auto on_surface = [&] {
    glm::vec3 p(u(rng), u(rng), u(rng));
    const int face = static_cast<int>(u(rng) * 6.0f) % 6;
    p[face % 3] = face < 3 ? 0.0f : 1.0f;
    return p;
  };
  tris.reserve(tris.size() + n);
  for (std::size_t made = 0; made < n;) {
    const glm::vec3 a = on_surface(), b = on_surface();
    if (glm::length(b - a) < 0.25f) continue;
    glm::vec3 side = glm::cross(b - a, glm::vec3(u(rng), u(rng), u(rng)) - 0.5f);
    if (glm::length(side) == 0.0f) continue;
    SceneTriangle t{};
    t.p[0] = a;
    t.p[1] = b;
    t.p[2] = a + 1e-3f * glm::normalize(side);
    const glm::vec3 normal = glm::normalize(glm::cross(t.p[1] - t.p[0], t.p[2] - t.p[0]));
    for (auto& nrm : t.n) nrm = normal;
    t.material = material;
    tris.push_back(t);
    ++made;
  }
}

void append_icosphere(std::vector<SceneTriangle>& tris, glm::vec3 center, float radius, int subdivisions,
                      std::uint32_t material) {
  subdivisions = std::clamp(subdivisions, 0, 10);
  // Icosahedron: cyclic permutations of (0, +-1, +-phi). Its faces are the vertex triples that
  // are pairwise at edge length 2; finding them by distance avoids a hand-written face table.
  const double phi = std::numbers::phi;
  std::vector<glm::dvec3> verts;
  for (int s1 : {-1, 1})
    for (int s2 : {-1, 1}) {
      verts.emplace_back(0.0, s1, s2 * phi);
      verts.emplace_back(s1, s2 * phi, 0.0);
      verts.emplace_back(s2 * phi, 0.0, s1);
    }
  auto is_edge = [&](int a, int b) { return std::abs(glm::length(verts[a] - verts[b]) - 2.0) < 1e-9; };
  std::vector<glm::ivec3> faces;
  for (int a = 0; a < 12; ++a)
    for (int b = a + 1; b < 12; ++b)
      for (int c = b + 1; c < 12; ++c) {
        if (!is_edge(a, b) || !is_edge(b, c) || !is_edge(a, c)) continue;
        const glm::dvec3 n = glm::cross(verts[b] - verts[a], verts[c] - verts[a]);
        const bool outward = glm::dot(n, verts[a] + verts[b] + verts[c]) > 0.0;
        faces.push_back(outward ? glm::ivec3(a, b, c) : glm::ivec3(a, c, b));
      }
  for (auto& v : verts) v = glm::normalize(v);

  // Each subdivision splits a face in four at its edge midpoints; the midpoint of an edge is
  // created once (cache keyed by the edge's vertex pair) so both faces share it exactly.
  for (int level = 0; level < subdivisions; ++level) {
    std::unordered_map<std::uint64_t, int> midpoint_of_edge;
    midpoint_of_edge.reserve(faces.size() * 2);
    auto midpoint = [&](int a, int b) {
      const std::uint64_t key = (std::uint64_t(std::min(a, b)) << 32) | std::uint32_t(std::max(a, b));
      auto [it, inserted] = midpoint_of_edge.try_emplace(key, int(verts.size()));
      if (inserted) verts.push_back(glm::normalize(verts[a] + verts[b]));
      return it->second;
    };
    std::vector<glm::ivec3> finer;
    finer.reserve(faces.size() * 4);
    for (const glm::ivec3& f : faces) {
      const int ab = midpoint(f.x, f.y), bc = midpoint(f.y, f.z), ca = midpoint(f.z, f.x);
      finer.emplace_back(f.x, ab, ca);
      finer.emplace_back(ab, f.y, bc);
      finer.emplace_back(ca, bc, f.z);
      finer.emplace_back(ab, bc, ca);
    }
    faces = std::move(finer);
  }

  // Final positions once per vertex, so shared vertices are bit-identical.
  std::vector<glm::vec3> positions(verts.size()), normals(verts.size());
  std::vector<glm::vec2> uvs(verts.size());
  for (std::size_t i = 0; i < verts.size(); ++i) {
    normals[i] = glm::vec3(verts[i]);
    positions[i] = center + radius * normals[i];
    uvs[i] = glm::vec2(float(std::atan2(verts[i].z, verts[i].x) / (2.0 * std::numbers::pi) + 0.5),
                       float(std::asin(std::clamp(verts[i].y, -1.0, 1.0)) / std::numbers::pi + 0.5));
  }
  tris.reserve(tris.size() + faces.size());
  for (const glm::ivec3& f : faces)
    emit(tris, positions[f.x], positions[f.y], positions[f.z], normals[f.x], normals[f.y], normals[f.z], uvs[f.x],
         uvs[f.y], uvs[f.z], material);
}

void append_lathe(std::vector<SceneTriangle>& tris, glm::vec3 base, std::span<const glm::vec2> profile, int segments,
                  std::uint32_t material, LatheCaps caps) {
  if (profile.size() < 2 || segments < 3) return;
  const std::size_t rings = profile.size();
  const int n = segments;

  // Angle runs clockwise seen from above (x towards -z) so that bottom-to-top profile order
  // gives counter-clockwise, outward-facing quads.
  std::vector<glm::vec3> radial(n);
  for (int j = 0; j < n; ++j) {
    const double a = 2.0 * std::numbers::pi * j / n;
    radial[j] = glm::vec3(float(std::cos(a)), 0.0f, float(-std::sin(a)));
  }
  // All ring vertices computed once; the seam reuses index 0.
  std::vector<glm::vec3> ring(rings * n);
  for (std::size_t k = 0; k < rings; ++k)
    for (int j = 0; j < n; ++j) ring[k * n + j] = base + glm::vec3(0.0f, profile[k].y, 0.0f) + profile[k].x * radial[j];
  auto at = [&](std::size_t k, int j) { return ring[k * n + (j % n)]; };
  auto u_of = [&](int j) { return float(j) / float(n); };

  tris.reserve(tris.size() + (rings - 1) * n * 2 + (caps.bottom ? n : 0) + (caps.top ? n : 0));
  for (std::size_t k = 0; k + 1 < rings; ++k) {
    const glm::vec2 a = profile[k], b = profile[k + 1];
    if (a == b || (a.x <= 0.0f && b.x <= 0.0f)) continue;
    // Outward normal of this profile segment in the (radial, up) plane.
    glm::vec2 pn(b.y - a.y, -(b.x - a.x));
    pn /= glm::length(pn);
    const float v0 = float(k) / float(rings - 1), v1 = float(k + 1) / float(rings - 1);
    for (int j = 0; j < n; ++j) {
      const glm::vec3 n0 = radial[j] * pn.x + glm::vec3(0, pn.y, 0);
      const glm::vec3 n1 = radial[(j + 1) % n] * pn.x + glm::vec3(0, pn.y, 0);
      const glm::vec3 p00 = at(k, j), p01 = at(k, j + 1), p10 = at(k + 1, j), p11 = at(k + 1, j + 1);
      // A ring of radius 0 is a single point on the axis: only one triangle per facet.
      if (a.x > 0.0f)
        emit(tris, p00, p01, p11, n0, n1, n1, {u_of(j), v0}, {u_of(j + 1), v0}, {u_of(j + 1), v1}, material);
      if (b.x > 0.0f) emit(tris, p00, p11, p10, n0, n1, n0, {u_of(j), v0}, {u_of(j + 1), v1}, {u_of(j), v1}, material);
    }
  }
  auto cap = [&](std::size_t k, bool up) {
    if (profile[k].x <= 0.0f) return;
    const glm::vec3 c = base + glm::vec3(0.0f, profile[k].y, 0.0f);
    const glm::vec3 nrm(0.0f, up ? 1.0f : -1.0f, 0.0f);
    for (int j = 0; j < n; ++j) {
      const glm::vec3 r0 = at(k, j), r1 = at(k, j + 1);
      const glm::vec2 t0(0.5f + 0.5f * radial[j].x, 0.5f - 0.5f * radial[j].z);
      const glm::vec2 t1(0.5f + 0.5f * radial[(j + 1) % n].x, 0.5f - 0.5f * radial[(j + 1) % n].z);
      if (up)
        emit(tris, c, r0, r1, nrm, nrm, nrm, {0.5f, 0.5f}, t0, t1, material);
      else
        emit(tris, c, r1, r0, nrm, nrm, nrm, {0.5f, 0.5f}, t1, t0, material);
    }
  };
  if (caps.bottom) cap(0, false);
  if (caps.top) cap(rings - 1, true);
}

void append_cylinder(std::vector<SceneTriangle>& tris, glm::vec3 base_center, float radius, float height, int segments,
                     std::uint32_t material, bool caps) {
  const glm::vec2 profile[2] = {{radius, 0.0f}, {radius, height}};
  append_lathe(tris, base_center, profile, segments, material, LatheCaps{caps, caps});
}

}  // namespace px
