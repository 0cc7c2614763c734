// Built-in scenes (Cornell box from its published data, the procedural atrium, the many-lights
// rooms) and the mesh primitives they are made of.
#include "scene/primitives.h"
#include "scene/scene_loader.h"

#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <map>
#include <optional>

namespace px {
namespace {

// ---------------------------------------------------------------------------------------------
// Helpers

using PositionBits = std::array<std::uint32_t, 3>;
PositionBits bits(glm::vec3 p) {
  return {std::bit_cast<std::uint32_t>(p.x), std::bit_cast<std::uint32_t>(p.y), std::bit_cast<std::uint32_t>(p.z)};
}

// Closed and consistently oriented: every directed edge a->b appears exactly once and its
// reverse b->a exactly once, comparing vertex positions bit for bit.
void expect_closed(const std::vector<SceneTriangle>& tris, const std::string& label) {
  std::map<std::pair<PositionBits, PositionBits>, int> directed;
  for (const SceneTriangle& t : tris)
    for (int e = 0; e < 3; ++e) ++directed[{bits(t.p[e]), bits(t.p[(e + 1) % 3])}];
  std::size_t bad = 0;
  for (const auto& [edge, count] : directed) {
    const auto reverse = directed.find({edge.second, edge.first});
    if (count != 1 || reverse == directed.end() || reverse->second != 1) ++bad;
  }
  EXPECT_EQ(bad, 0u) << label << ": " << bad << " of " << directed.size()
                     << " directed edges are not matched exactly once by their reverse";
}

void expect_outward(const std::vector<SceneTriangle>& tris, glm::vec3 inside, const std::string& label) {
  for (std::size_t i = 0; i < tris.size(); ++i) {
    const SceneTriangle& t = tris[i];
    const glm::vec3 centroid = (t.p[0] + t.p[1] + t.p[2]) / 3.0f;
    ASSERT_GT(glm::dot(geometric_normal(t), centroid - inside), 0.0f) << label << " triangle " << i;
  }
}

void expect_all_valid(const Scene& s, const std::string& label) {
  ASSERT_FALSE(s.triangles.empty()) << label;
  std::size_t bad = 0, bad_normal = 0, bad_material = 0;
  for (const SceneTriangle& t : s.triangles) {
    bad += !has_finite_positions(t) || is_degenerate(t) || glm::length(geometric_normal(t)) < 0.5f;
    bad_material += t.material >= s.materials.size();
    for (const glm::vec3& n : t.n) bad_normal += !(std::abs(glm::length(n) - 1.0f) < 1e-3f);
  }
  EXPECT_EQ(bad, 0u) << label << ": non-finite or degenerate triangles";
  EXPECT_EQ(bad_normal, 0u) << label << ": shading normals not unit length";
  EXPECT_EQ(bad_material, 0u) << label << ": material index out of range";
  for (const Material& m : s.materials) {
    EXPECT_LT(m.diffuse_texture, int(s.textures.size())) << label;
    EXPECT_LT(m.alpha_texture, int(s.textures.size())) << label;
  }
  for (const Texture& t : s.textures) EXPECT_EQ(t.rgba.size(), std::size_t(t.width) * t.height * 4) << label;
  for (std::size_t i = 1; i < s.camera_path.size(); ++i)
    EXPECT_GT(s.camera_path[i].time, s.camera_path[i - 1].time) << label;
  EXPECT_GT(s.meters_per_unit, 0.0f);
}

struct Bounds {
  glm::vec3 lo{1e30f}, hi{-1e30f};
};
Bounds bounds_of(const std::vector<SceneTriangle>& tris) {
  Bounds b;
  for (const SceneTriangle& t : tris)
    for (const glm::vec3& p : t.p) b.lo = glm::min(b.lo, p), b.hi = glm::max(b.hi, p);
  return b;
}

// Nearest hit along a ray (Moller-Trumbore; a test oracle, not the renderer's intersector).
std::optional<std::size_t> first_hit(const std::vector<SceneTriangle>& tris, glm::vec3 o, glm::vec3 d) {
  float best = 1e30f;
  std::optional<std::size_t> hit;
  for (std::size_t i = 0; i < tris.size(); ++i) {
    const glm::vec3 e1 = tris[i].p[1] - tris[i].p[0], e2 = tris[i].p[2] - tris[i].p[0];
    const glm::vec3 pv = glm::cross(d, e2);
    const float det = glm::dot(e1, pv);
    if (std::abs(det) < 1e-12f) continue;
    const glm::vec3 tv = o - tris[i].p[0];
    const float u = glm::dot(tv, pv) / det;
    if (u < 0.0f || u > 1.0f) continue;
    const glm::vec3 qv = glm::cross(tv, e1);
    const float v = glm::dot(d, qv) / det;
    if (v < 0.0f || u + v > 1.0f) continue;
    const float t = glm::dot(e2, qv) / det;
    if (t > 1e-4f && t < best) best = t, hit = i;
  }
  return hit;
}

// Distance from p to the triangle (closest point by barycentric region; Ericson, Real-Time
// Collision Detection 5.1.5).
float distance_to_triangle(glm::vec3 p, const SceneTriangle& t) {
  const glm::vec3 a = t.p[0], b = t.p[1], c = t.p[2];
  const glm::vec3 ab = b - a, ac = c - a, ap = p - a;
  const float d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return glm::distance(p, a);
  const glm::vec3 bp = p - b;
  const float d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return glm::distance(p, b);
  const float vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return glm::distance(p, a + ab * (d1 / (d1 - d3)));
  const glm::vec3 cp = p - c;
  const float d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return glm::distance(p, c);
  const float vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return glm::distance(p, a + ac * (d2 / (d2 - d6)));
  const float va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return glm::distance(p, b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))));
  const float denom = 1.0f / (va + vb + vc);
  return glm::distance(p, a + ab * (vb * denom) + ac * (vc * denom));
}

// ---------------------------------------------------------------------------------------------
// Primitives

TEST(Primitives, IcosphereIsClosedOutwardAndOnTheSphere) {
  for (int level : {0, 1, 3}) {
    std::vector<SceneTriangle> tris;
    const glm::vec3 c(1.5f, -2.0f, 0.25f);
    append_icosphere(tris, c, 2.0f, level, 7);
    EXPECT_EQ(tris.size(), 20u << (2 * level));
    expect_closed(tris, "icosphere " + std::to_string(level));
    expect_outward(tris, c, "icosphere");
    for (const SceneTriangle& t : tris) {
      EXPECT_EQ(t.material, 7u);
      for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(glm::distance(t.p[k], c), 2.0f, 1e-5f);
        EXPECT_GT(glm::dot(t.n[k], t.p[k] - c), 0.0f);
      }
    }
  }
}

TEST(Primitives, BoxIsClosedWithOutwardNormals) {
  std::vector<SceneTriangle> tris;
  append_box(tris, {-1.0f, 0.0f, 2.0f}, {3.0f, 0.5f, 4.0f}, 2);
  ASSERT_EQ(tris.size(), 12u);
  expect_closed(tris, "box");
  expect_outward(tris, {1.0f, 0.25f, 3.0f}, "box");
  double area = 0.0;
  for (const SceneTriangle& t : tris) {
    area += triangle_area(t);
    EXPECT_EQ(t.n[0], geometric_normal(t));
  }
  EXPECT_NEAR(area, 2.0 * (4.0 * 0.5 + 4.0 * 2.0 + 0.5 * 2.0), 1e-5);
}

TEST(Primitives, OrientedBoxStaysOutwardUnderMirroring) {
  for (const glm::vec3 scale : {glm::vec3(1, 2, 3), glm::vec3(-1, 2, 3)}) {
    const glm::mat4 m = glm::scale(glm::rotate(glm::translate(glm::mat4(1.0f), {5, 0, 0}), 0.7f, {0, 1, 0}), scale);
    std::vector<SceneTriangle> tris;
    append_oriented_box(tris, glm::vec3(-0.5f), glm::vec3(0.5f), m, 0);
    ASSERT_EQ(tris.size(), 12u);
    expect_closed(tris, "oriented box");
    expect_outward(tris, glm::vec3(m * glm::vec4(0, 0, 0, 1)), "oriented box");
  }
}

TEST(Primitives, DistanceOracle) {
  SceneTriangle t;
  t.p[0] = {0, 0, 0};
  t.p[1] = {2, 0, 0};
  t.p[2] = {0, 2, 0};
  EXPECT_NEAR(distance_to_triangle({0.5f, 0.5f, 3.0f}, t), 3.0f, 1e-6f);
  EXPECT_NEAR(distance_to_triangle({-1.0f, -1.0f, 0.0f}, t), std::sqrt(2.0f), 1e-6f);
  EXPECT_NEAR(distance_to_triangle({2.0f, 2.0f, 0.0f}, t), std::sqrt(2.0f), 1e-6f);
}

TEST(Primitives, QuadWindingAndFacing) {
  std::vector<SceneTriangle> tris;
  append_quad(tris, {0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, 0);
  ASSERT_EQ(tris.size(), 2u);
  for (const SceneTriangle& t : tris) EXPECT_GT(geometric_normal(t).z, 0.999f);
  tris.clear();
  append_quad_facing(tris, {0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, -1}, 0);
  ASSERT_EQ(tris.size(), 2u);
  for (const SceneTriangle& t : tris) EXPECT_LT(geometric_normal(t).z, -0.999f);
  // A quad with a repeated corner emits only its non-degenerate half.
  tris.clear();
  append_quad(tris, {0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {1, 1, 0}, 0);
  EXPECT_EQ(tris.size(), 1u);
}

TEST(Primitives, LathesAndCylindersAreClosed) {
  std::vector<SceneTriangle> cyl;
  append_cylinder(cyl, {1, 2, 3}, 0.5f, 2.0f, 24, 0);
  EXPECT_EQ(cyl.size(), 24u * 4u);
  expect_closed(cyl, "cylinder");
  expect_outward(cyl, {1, 3, 3}, "cylinder");
  // A double cone closes on the axis at both ends without caps or degenerate triangles.
  const glm::vec2 profile[] = {{0.0f, 0.0f}, {1.0f, 0.5f}, {0.8f, 1.0f}, {0.0f, 1.5f}};
  std::vector<SceneTriangle> spindle;
  append_lathe(spindle, {0, 0, 0}, profile, 16, 0);
  EXPECT_EQ(spindle.size(), 16u * 4u);
  expect_closed(spindle, "lathe");
  expect_outward(spindle, {0, 0.75f, 0}, "lathe");
  for (const SceneTriangle& t : spindle) EXPECT_FALSE(is_degenerate(t));
}

// ---------------------------------------------------------------------------------------------
// Dispatch

TEST(BuiltinScenes, EveryBuiltinIsValid) {
  const auto& names = builtin_scene_names();
  ASSERT_EQ(names.size(), 4u);
  for (const std::string& name : names) {
    const Scene s = name == "atrium" ? make_builtin_scene(name, {{"detail", 0.05}}) : make_builtin_scene(name);
    expect_all_valid(s, name);
    EXPECT_EQ(s.name, name);
    const bool emissive =
        std::any_of(s.materials.begin(), s.materials.end(), [](const Material& m) { return m.is_emissive(); });
    EXPECT_TRUE(emissive || s.sun.enabled || s.sky.enabled) << name << " has no light";
    EXPECT_FALSE(s.camera_path.empty()) << name;
  }
}

TEST(BuiltinScenes, RefusesUnknownNamesAndParameters) {
  EXPECT_THROW(make_builtin_scene("sponza"), SceneError);
  EXPECT_THROW(make_builtin_scene("cornell", {{"size", 2}}), SceneError);
  EXPECT_THROW(make_builtin_scene("atrium", {{"detail", 0.0}}), SceneError);
  EXPECT_THROW(make_builtin_scene("atrium", {{"detail", "high"}}), SceneError);
  EXPECT_THROW(make_builtin_scene("atrium", {{"seed", 1.5}}), SceneError);
  try {
    make_builtin_scene("atrium", {{"detial", 1.0}});
    FAIL() << "no error";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("detial"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------------------------------------
// Cornell box

TEST(Cornell, MatchesThePublishedDimensions) {
  const Scene s = make_builtin_scene("cornell");
  const Bounds b = bounds_of(s.triangles);
  EXPECT_NEAR(b.lo.x, 0.0f, 1e-3f);
  EXPECT_NEAR(b.lo.y, 0.0f, 1e-3f);
  EXPECT_NEAR(b.lo.z, 0.0f, 1e-3f);
  EXPECT_NEAR(b.hi.x, 556.0f, 1e-3f);
  EXPECT_NEAR(b.hi.y, 548.8f, 1e-3f);
  EXPECT_NEAR(b.hi.z, 559.2f, 1e-3f);
  EXPECT_FLOAT_EQ(s.meters_per_unit, 0.001f);
  EXPECT_EQ(s.camera.position, glm::vec3(278.0f, 273.0f, -800.0f));
  EXPECT_EQ(s.camera.target, glm::vec3(278.0f, 273.0f, 0.0f));
  EXPECT_NEAR(s.camera.vfov_deg, 39.3f, 0.05f);
  // The blocks' heights and the light's size.
  float short_top = 0.0f, tall_top = 0.0f;
  double light_area = 0.0;
  for (const SceneTriangle& t : s.triangles) {
    const Material& m = s.materials[t.material];
    if (m.is_emissive()) {
      light_area += triangle_area(t);
      EXPECT_EQ(m.emission, glm::vec3(17.0f, 12.0f, 4.0f));
      EXPECT_LT(geometric_normal(t).y, -0.999f) << "light must face down";
    }
    const float top = std::max({t.p[0].y, t.p[1].y, t.p[2].y});
    const glm::vec3 c = (t.p[0] + t.p[1] + t.p[2]) / 3.0f;
    if (top < 200.0f && c.x > 50.0f && c.x < 300.0f) short_top = std::max(short_top, top);
    if (top > 200.0f && top < 400.0f) tall_top = std::max(tall_top, top);
  }
  EXPECT_NEAR(light_area, 130.0 * 105.0, 1e-2);
  EXPECT_FLOAT_EQ(short_top, 165.0f);
  EXPECT_FLOAT_EQ(tall_top, 330.0f);
  // Path: a short sideways dolly at the published camera's height and depth.
  for (const CameraKey& k : s.camera_path) {
    EXPECT_FLOAT_EQ(k.position.y, 273.0f);
    EXPECT_FLOAT_EQ(k.position.z, -800.0f);
  }
  EXPECT_LE(s.camera_path.back().time, 10.0f);
}

TEST(Cornell, SurfacesFaceTheirViewers) {
  const Scene s = make_builtin_scene("cornell");
  const glm::vec3 room_center(278.0f, 274.4f, 279.6f);
  for (const SceneTriangle& t : s.triangles) {
    const glm::vec3 c = (t.p[0] + t.p[1] + t.p[2]) / 3.0f;
    const glm::vec3 n = geometric_normal(t);
    const bool on_shell = c.x < 1.0f || c.x > 548.0f || c.y < 1.0f || c.y > 548.0f || c.z > 558.0f;
    if (on_shell) {
      EXPECT_GT(glm::dot(n, room_center - c), 0.0f) << "wall facing out at " << c.x << "," << c.y << "," << c.z;
    }
  }
  // Block sides face away from their block's axis.
  auto check_block = [&](glm::vec2 axis, float height) {
    int sides = 0;
    for (const SceneTriangle& t : s.triangles) {
      const glm::vec3 c = (t.p[0] + t.p[1] + t.p[2]) / 3.0f;
      if (glm::distance(glm::vec2(c.x, c.z), axis) > 150.0f || c.y > height || std::abs(geometric_normal(t).y) > 0.5f)
        continue;
      EXPECT_GT(glm::dot(glm::vec2(geometric_normal(t).x, geometric_normal(t).z), glm::vec2(c.x, c.z) - axis), 0.0f);
      ++sides;
    }
    EXPECT_EQ(sides, 8);
  };
  check_block({185.5f, 169.0f}, 165.0f);
  check_block({368.5f, 351.25f}, 330.0f);
}

TEST(Cornell, RedWallIsOnTheLeftOfTheImage) {
  const Scene s = make_builtin_scene("cornell");
  const glm::vec3 forward = glm::normalize(s.camera.target - s.camera.position);
  const glm::vec3 right = glm::normalize(glm::cross(forward, s.camera.up));  // right-handed camera
  const float tan_half = std::tan(glm::radians(0.5f * s.camera.vfov_deg));
  auto colour_at = [&](float x_ndc) {  // x_ndc in [-1, 1], left to right, square image
    const glm::vec3 d = glm::normalize(forward + right * (x_ndc * tan_half));
    const auto hit = first_hit(s.triangles, s.camera.position, d);
    return hit ? s.materials[s.triangles[*hit].material].name : std::string("miss");
  };
  EXPECT_EQ(colour_at(-0.95f), "red");
  EXPECT_EQ(colour_at(0.95f), "green");
  EXPECT_EQ(colour_at(0.0f), "white");
}

TEST(Cornell, GlossyVariantHasAGlossyBlockAndAClosedMirrorSphere) {
  const Scene s = make_builtin_scene("cornell-glossy");
  std::optional<std::uint32_t> glossy, mirror;
  for (std::uint32_t i = 0; i < s.materials.size(); ++i) {
    if (s.materials[i].mirror) mirror = i;
    if (!s.materials[i].mirror && s.materials[i].specular.x > 0.0f) glossy = i;
  }
  ASSERT_TRUE(glossy && mirror);
  EXPECT_NEAR(s.materials[*glossy].roughness, 0.2f, 0.05f);
  std::vector<SceneTriangle> sphere;
  std::size_t glossy_tris = 0;
  for (const SceneTriangle& t : s.triangles) {
    if (t.material == *mirror) sphere.push_back(t);
    if (t.material == *glossy) {
      ++glossy_tris;
      EXPECT_GE(std::max({t.p[0].y, t.p[1].y, t.p[2].y}), 0.0f);
    }
  }
  EXPECT_EQ(glossy_tris, 10u);  // the tall block: top and four sides
  ASSERT_FALSE(sphere.empty());
  expect_closed(sphere, "mirror sphere");
  // Inside the room, clear of the floor and walls.
  const Bounds b = bounds_of(sphere);
  EXPECT_GT(b.lo.y, 0.0f);
  EXPECT_GT(b.lo.x, 0.0f);
  EXPECT_LT(b.hi.x, 549.0f);
  EXPECT_GT(b.lo.z, 0.0f);
}

// ---------------------------------------------------------------------------------------------
// Atrium

TEST(Atrium, DefaultDetailIsLarge) {
  // (How long generation takes is measured, not asserted: tests check behaviour only.)
  const Scene s = make_builtin_scene("atrium");
  EXPECT_GE(s.triangles.size(), 500000u);
  expect_all_valid(s, "atrium");
}

TEST(Atrium, SmallDetailIsSmallAndKeepsFoliage) {
  const Scene s = make_builtin_scene("atrium", {{"detail", 0.05}});
  EXPECT_LT(s.triangles.size(), 20000u);
  EXPECT_GT(s.triangles.size(), 1000u);
  std::size_t foliage = 0;
  for (const SceneTriangle& t : s.triangles) {
    const Material& m = s.materials[t.material];
    if (m.alpha_texture < 0) continue;
    ++foliage;
    ASSERT_LT(m.alpha_texture, int(s.textures.size()));
  }
  EXPECT_GT(foliage, 100u);
  // The leaf texture cuts out: both transparent and opaque texels, and coloured leaves.
  ASSERT_FALSE(s.textures.empty());
  const Texture& tex = s.textures[0];
  std::size_t opaque = 0, clear = 0;
  for (std::size_t i = 0; i < tex.rgba.size(); i += 4) {
    (tex.rgba[i + 3] >= 0.5f ? opaque : clear)++;
    if (tex.rgba[i + 3] >= 0.5f) {
      EXPECT_GT(tex.rgba[i + 1], tex.rgba[i + 2]);  // green over blue
    }
  }
  EXPECT_GT(opaque, tex.rgba.size() / 4 / 10);
  EXPECT_GT(clear, tex.rgba.size() / 4 / 10);
}

TEST(Atrium, DetailScalesTessellationNotLayout) {
  const Scene small = make_builtin_scene("atrium", {{"detail", 0.05}});
  const Scene medium = make_builtin_scene("atrium", {{"detail", 0.3}});
  EXPECT_GT(medium.triangles.size(), 4 * small.triangles.size());
  const Bounds a = bounds_of(small.triangles), b = bounds_of(medium.triangles);
  // Same walls, whatever the detail (foliage can move the bounds only inside them).
  EXPECT_EQ(a.lo.y, b.lo.y);
  EXPECT_EQ(a.hi.y, b.hi.y);
  EXPECT_EQ(a.lo.x, b.lo.x);
  EXPECT_EQ(a.hi.z, b.hi.z);
}

TEST(Atrium, IsDeterministicPerSeed) {
  const Scene a = make_builtin_scene("atrium", {{"detail", 0.05}, {"seed", 7}});
  const Scene b = make_builtin_scene("atrium", {{"detail", 0.05}, {"seed", 7}});
  const Scene c = make_builtin_scene("atrium", {{"detail", 0.05}, {"seed", 8}});
  ASSERT_EQ(a.triangles.size(), b.triangles.size());
  bool same = true, differs = false;
  for (std::size_t i = 0; i < a.triangles.size(); ++i) {
    same &= a.triangles[i].p[0] == b.triangles[i].p[0];
    differs |= i < c.triangles.size() && a.triangles[i].p[0] != c.triangles[i].p[0];
  }
  EXPECT_TRUE(same);
  EXPECT_TRUE(differs);
}

TEST(Atrium, LitBySunAndSkyWithAWalkingCamera) {
  const Scene s = make_builtin_scene("atrium", {{"detail", 0.05}});
  EXPECT_TRUE(s.sun.enabled);
  EXPECT_TRUE(s.sky.enabled);
  EXPECT_NEAR(glm::length(s.sun.direction), 1.0f, 1e-5f);
  EXPECT_GT(s.sun.direction.y, 0.3f);
  EXPECT_FLOAT_EQ(s.meters_per_unit, 1.0f);
  // Sunlit albedo-0.5 ground is about 1 in radiance (see builtin_atrium.cpp).
  const float solid_angle = glm::pi<float>() * std::pow(glm::radians(s.sun.angular_radius_deg), 2.0f);
  const float ground = 0.5f / glm::pi<float>() * s.sun.radiance.x * solid_angle * s.sun.direction.y;
  EXPECT_GT(ground, 0.5f);
  EXPECT_LT(ground, 2.0f);
  ASSERT_GE(s.camera_path.size(), 5u);
  EXPECT_GE(s.camera_path.back().time - s.camera_path.front().time, 5.0f);
  // Every key is inside the courtyard at eye height and at least 25 cm from any surface (so
  // the camera never starts inside a column or a shrub).
  const Bounds walls = bounds_of(s.triangles);
  for (const CameraKey& k : s.camera_path) {
    EXPECT_GT(k.position.x, walls.lo.x);
    EXPECT_LT(k.position.x, walls.hi.x);
    EXPECT_GT(k.position.z, walls.lo.z);
    EXPECT_LT(k.position.z, walls.hi.z);
    EXPECT_NEAR(k.position.y, 1.7f, 0.3f);
    float nearest = 1e30f;
    for (const SceneTriangle& t : s.triangles) nearest = std::min(nearest, distance_to_triangle(k.position, t));
    EXPECT_GT(nearest, 0.25f) << "camera key at t = " << k.time << " s is inside or against geometry";
  }
}

// ---------------------------------------------------------------------------------------------
// Rooms (many lights)

// Room (column along x, row along z) of a point, on the generator's 4 m pitch.
glm::ivec2 room_of(glm::vec3 p) { return {int(std::floor(p.x / 4.0f)), int(std::floor(p.z / 4.0f))}; }

struct Lamp {
  glm::vec3 centre{0.0f};
  double area = 0.0;
  glm::vec3 emission{0.0f};
  int triangles = 0;
};

// The emitters grouped by material (every lamp has its own).
std::map<std::uint32_t, Lamp> lamps_of(const Scene& s) {
  std::map<std::uint32_t, Lamp> lamps;
  for (const SceneTriangle& t : s.triangles) {
    const Material& m = s.materials[t.material];
    if (!m.is_emissive()) continue;
    Lamp& l = lamps[t.material];
    const double a = triangle_area(t);
    l.centre += float(a) * (t.p[0] + t.p[1] + t.p[2]) / 3.0f;
    l.area += a;
    l.emission = m.emission;
    ++l.triangles;
  }
  for (auto& [material, l] : lamps) l.centre /= float(l.area);
  return lamps;
}

float luminance_of(glm::vec3 c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

TEST(Rooms, SixteenRoomsOfSixtyFourLamps) {
  const Scene s = make_builtin_scene("rooms");
  expect_all_valid(s, "rooms");
  EXPECT_FALSE(s.sun.enabled);
  EXPECT_FALSE(s.sky.enabled);
  std::size_t emissive = 0;
  for (const SceneTriangle& t : s.triangles) emissive += s.materials[t.material].is_emissive();
  EXPECT_EQ(emissive, 2048u);
  const auto lamps = lamps_of(s);
  ASSERT_EQ(lamps.size(), 1024u);
  std::map<std::pair<int, int>, int> per_room;
  for (const auto& [material, l] : lamps) {
    EXPECT_EQ(l.triangles, 2) << "lamp " << material << " is not one quad";
    const glm::ivec2 r = room_of(l.centre);
    ++per_room[{r.x, r.y}];
  }
  ASSERT_EQ(per_room.size(), 16u);
  for (const auto& [room, count] : per_room) {
    EXPECT_GE(room.first, 0);
    EXPECT_LT(room.first, 4);
    EXPECT_GE(room.second, 0);
    EXPECT_LT(room.second, 4);
    EXPECT_EQ(count, 64) << "room " << room.first << "," << room.second;
  }
  // A building 16 x 3 x 16 m (plus half a wall's thickness all round).
  const Bounds b = bounds_of(s.triangles);
  EXPECT_NEAR(b.hi.x - b.lo.x, 16.2f, 1e-3f);
  EXPECT_NEAR(b.hi.z - b.lo.z, 16.2f, 1e-3f);
  EXPECT_NEAR(b.hi.y - b.lo.y, 3.0f, 1e-3f);
}

TEST(Rooms, EveryLampFacesDownJustUnderItsRoomsCeiling) {
  const Scene s = make_builtin_scene("rooms");
  std::size_t checked = 0;
  for (const SceneTriangle& t : s.triangles) {
    if (!s.materials[t.material].is_emissive()) continue;
    EXPECT_LT(geometric_normal(t).y, -0.999f) << "a lamp must face down";
    const glm::vec3 c = (t.p[0] + t.p[1] + t.p[2]) / 3.0f;
    // Straight up from just above the lamp: the ceiling, within 5 cm.
    const auto up = first_hit(s.triangles, c + glm::vec3(0.0f, 1e-3f, 0.0f), {0.0f, 1.0f, 0.0f});
    ASSERT_TRUE(up.has_value());
    const SceneTriangle& above = s.triangles[*up];
    EXPECT_EQ(s.materials[above.material].name, "ceiling");
    EXPECT_GT(above.p[0].y - c.y, 0.0f);
    EXPECT_LT(above.p[0].y - c.y, 0.05f);
    // Inside its room, clear of the walls (0.1 m either side of the grid lines).
    const glm::ivec2 r = room_of(c);
    for (const glm::vec3& p : t.p) {
      EXPECT_GT(p.x, 4.0f * float(r.x) + 0.1f);
      EXPECT_LT(p.x, 4.0f * float(r.x + 1) - 0.1f);
      EXPECT_GT(p.z, 4.0f * float(r.y) + 0.1f);
      EXPECT_LT(p.z, 4.0f * float(r.y + 1) - 0.1f);
    }
    ++checked;
  }
  EXPECT_EQ(checked, 2048u);
}

TEST(Rooms, LampsDifferInPowerAndColour) {
  const Scene s = make_builtin_scene("rooms");
  double lo = 1e30, hi = 0.0;
  int warm = 0, cool = 0, neutral = 0;
  std::map<std::array<float, 3>, int> distinct;
  for (const auto& [material, l] : lamps_of(s)) {
    const double power = glm::pi<double>() * l.area * luminance_of(l.emission);
    lo = std::min(lo, power);
    hi = std::max(hi, power);
    const float r = l.emission.x, b = l.emission.z;
    if (r > 1.3f * b)
      ++warm;
    else if (b > 1.15f * r)
      ++cool;
    else
      ++neutral;
    ++distinct[{l.emission.x, l.emission.y, l.emission.z}];
  }
  EXPECT_GT(hi / lo, 10.0) << "powers " << lo << " to " << hi;
  EXPECT_LT(hi / lo, 40.0) << "powers " << lo << " to " << hi;
  EXPECT_GT(warm, 200);
  EXPECT_GT(cool, 200);
  EXPECT_GT(neutral, 200);
  EXPECT_EQ(distinct.size(), 1024u);
}

TEST(Rooms, CameraSeesItsRoomAndTheNextThroughTheDoorway) {
  const Scene s = make_builtin_scene("rooms");
  const glm::ivec2 home = room_of(s.camera.position);
  EXPECT_EQ(home, glm::ivec2(1, 1));
  for (const CameraKey& k : s.camera_path) EXPECT_EQ(room_of(k.position), home);
  // Primary rays of a 16:9 image (as the renders are), traced by brute force.
  const glm::vec3 forward = glm::normalize(s.camera.target - s.camera.position);
  const glm::vec3 right = glm::normalize(glm::cross(forward, s.camera.up));
  const glm::vec3 up = glm::cross(right, forward);
  const float tan_half = std::tan(glm::radians(0.5f * s.camera.vfov_deg)), aspect = 16.0f / 9.0f;
  std::map<std::pair<int, int>, int> seen;
  int misses = 0, rays = 0;
  for (int y = 0; y < 18; ++y)
    for (int x = 0; x < 32; ++x) {
      const float sx = (2.0f * (float(x) + 0.5f) / 32.0f - 1.0f) * tan_half * aspect;
      const float sy = (1.0f - 2.0f * (float(y) + 0.5f) / 18.0f) * tan_half;
      const glm::vec3 d = glm::normalize(forward + sx * right + sy * up);
      const auto hit = first_hit(s.triangles, s.camera.position, d);
      ++rays;
      if (!hit) {
        ++misses;
        continue;
      }
      const SceneTriangle& t = s.triangles[*hit];
      // Where the ray ends, not the triangle's centroid (floor and ceiling span every room).
      const glm::vec3 e1 = t.p[1] - t.p[0], e2 = t.p[2] - t.p[0], n = glm::cross(e1, e2);
      const glm::vec3 at = s.camera.position + d * (glm::dot(t.p[0] - s.camera.position, n) / glm::dot(d, n));
      const glm::ivec2 r = room_of(at);
      ++seen[{r.x, r.y}];
    }
  EXPECT_EQ(misses, 0) << "the building is closed";
  const int own = seen[{home.x, home.y}], next = seen[{home.x + 1, home.y}];
  EXPECT_GT(own, rays / 4) << "its own room fills much of the view";
  EXPECT_GT(next, rays / 50) << "the next room shows through the doorway";
}

TEST(Rooms, ParametersScaleTheGridAndTheLampsAndSeedsAreDeterministic) {
  const Scene small = make_builtin_scene("rooms", {{"grid", 2}, {"lamps", 3}});
  std::size_t emissive = 0;
  for (const SceneTriangle& t : small.triangles) emissive += small.materials[t.material].is_emissive();
  EXPECT_EQ(emissive, 2u * 4u * 9u);
  expect_all_valid(small, "rooms grid 2");
  const Scene a = make_builtin_scene("rooms", {{"seed", 3}});
  const Scene b = make_builtin_scene("rooms", {{"seed", 3}});
  const Scene c = make_builtin_scene("rooms", {{"seed", 4}});
  ASSERT_EQ(a.triangles.size(), b.triangles.size());
  ASSERT_EQ(a.materials.size(), c.materials.size());
  bool same = true, differs = false;
  for (std::size_t i = 0; i < a.materials.size(); ++i) {
    same &= a.materials[i].emission == b.materials[i].emission;
    differs |= a.materials[i].emission != c.materials[i].emission;
  }
  EXPECT_TRUE(same);
  EXPECT_TRUE(differs);
  EXPECT_THROW(make_builtin_scene("rooms", {{"grid", 0}}), SceneError);
  EXPECT_THROW(make_builtin_scene("rooms", {{"lamps", 17}}), SceneError);
  EXPECT_THROW(make_builtin_scene("rooms", {{"rooms", 4}}), SceneError);
}

}  // namespace
}  // namespace px
