// "atrium": a procedural colonnaded courtyard lit by sun and sky, built to stress what the
// Cornell box does not: many triangles (finely tessellated columns and arches), long thin
// shadows, alpha-tested foliage, and open sky.
//
// Layout (metres, y up): a 32 x 22 m courtyard closed by 9 m walls. A portico runs round it:
// 24 columns on a rectangle 4 m inside the walls carry an arcade of round arches, a cornice and
// a roof slab out to the walls. In the open centre, a stepped podium carries a tree; planters
// with shrubs stand around it. Trees and shrubs are clouds of alpha-masked leaf cards.
//
// Tessellation follows the `detail` parameter: every rate (facets round a column, rings along
// it, segments along an arch) scales with detail^0.75, foliage card counts with detail^1.5, so
// the triangle count grows about as detail^1.5 (until the minimum tessellations take over at
// very low detail). detail = 1 gives > 500k triangles; 0.05 about ten thousand.
//
// Lighting units: radiance relative to the renderer's exposure 1. The sun's radiance is chosen
// so that sunlit ground of albedo ~0.5 comes out near 1:
//   L_floor = albedo / pi * L_sun * solid_angle_sun * cos(theta)
//           ~ 0.5 / pi * 1.1e5 * 6.98e-5 (0.27 deg radius) * 0.8 ~ 1.0;
// the sky (zenith blue, pale horizon) adds roughly a third of that in the open.
#include "scene/builtin_scenes.h"
#include "scene/primitives.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace px {

namespace {

constexpr float kPi = std::numbers::pi_v<float>;

struct Tessellation {
  int column_facets;    // around a column
  int shaft_rings;      // along a column shaft
  int moulding_steps;   // along each rounded moulding of a column
  int arch_segments;    // along one arch
  int soffit_strips;    // across the rounded underside of an arch
  float foliage_scale;  // multiplies every foliage card count
};

Tessellation tessellation_for(double detail) {
  const double k = std::pow(detail, 0.75);
  auto rate = [&](double full, int min) { return std::max(min, int(std::lround(full * k))); };
  return {rate(96, 6), rate(32, 1), rate(10, 1), rate(256, 6), rate(12, 1), float(std::pow(detail, 1.5))};
}

enum : std::uint32_t { kFloor, kWall, kStone, kPodium, kTerracotta, kSoil, kBark, kLeaves, kMaterialCount };

std::vector<Material> atrium_materials() {
  std::vector<Material> m(kMaterialCount);
  auto diffuse = [&](std::uint32_t i, const char* name, glm::vec3 albedo) {
    m[i].name = name;
    m[i].diffuse = albedo;
  };
  diffuse(kFloor, "floor", {0.48f, 0.44f, 0.38f});
  diffuse(kWall, "plaster", {0.72f, 0.62f, 0.50f});
  diffuse(kStone, "stone", {0.78f, 0.76f, 0.71f});
  diffuse(kPodium, "polished_stone", {0.55f, 0.54f, 0.52f});
  m[kPodium].specular = glm::vec3(0.05f);
  m[kPodium].roughness = 0.15f;
  diffuse(kTerracotta, "terracotta", {0.45f, 0.20f, 0.10f});
  diffuse(kSoil, "soil", {0.12f, 0.08f, 0.05f});
  diffuse(kBark, "bark", {0.20f, 0.14f, 0.09f});
  // MTL semantics: albedo = Kd x map_Kd, so the leaf colour lives in the texture.
  diffuse(kLeaves, "leaves", glm::vec3(1.0f));
  m[kLeaves].diffuse_texture = 0;
  m[kLeaves].alpha_texture = 0;
  return m;
}

// ---------------------------------------------------------------------------------------------
// Leaf texture: a twig with alternating pointed leaves on a transparent background. Colour is
// linear; alpha is exactly 0 or 1 (the renderer cuts out alpha < 0.5).

Texture make_leaf_texture(std::uint64_t seed) {
  constexpr int kSize = 256;
  Texture tex;
  tex.path = "procedural:atrium-leaves";
  tex.width = tex.height = kSize;
  tex.rgba.assign(std::size_t(kSize) * kSize * 4, 0.0f);

  struct Leaf {
    glm::vec2 base, axis, side;  // axis: base -> tip; side: unit perpendicular
    float length, half_width;
    glm::vec3 colour;
  };
  GeneratorRng rng(seed ^ 0x1eafull);
  // The twig runs up the middle of the image (y grows downwards, as the rows are stored).
  const glm::vec2 twig_from(0.5f, 0.98f), twig_to(0.5f, 0.04f);
  std::vector<Leaf> leaves;
  const int kLeaves = 14;
  for (int i = 0; i < kLeaves; ++i) {
    const float t = 0.12f + 0.86f * float(i) / float(kLeaves - 1);
    const float side_sign = (i % 2 == 0) ? 1.0f : -1.0f;
    const float angle = side_sign * glm::radians(rng.range(35.0f, 60.0f));
    // Rotate the twig's direction (straight up) by the leaf's angle.
    const glm::vec2 up(0.0f, -1.0f);
    Leaf leaf;
    leaf.base = glm::mix(twig_from, twig_to, t);
    leaf.axis =
        glm::vec2(up.x * std::cos(angle) - up.y * std::sin(angle), up.x * std::sin(angle) + up.y * std::cos(angle));
    leaf.side = glm::vec2(-leaf.axis.y, leaf.axis.x);
    leaf.length = rng.range(0.24f, 0.36f) * (1.1f - 0.4f * t);
    leaf.half_width = leaf.length * rng.range(0.16f, 0.22f);
    leaf.colour = glm::vec3(rng.range(0.04f, 0.09f), rng.range(0.15f, 0.28f), rng.range(0.02f, 0.05f));
    leaves.push_back(leaf);
  }
  // Top leaf continuing the twig.
  leaves.push_back(
      {twig_to + glm::vec2(0.0f, 0.02f), {0.0f, -1.0f}, {1.0f, 0.0f}, 0.2f, 0.045f, {0.07f, 0.24f, 0.04f}});

  const glm::vec3 twig_colour(0.10f, 0.07f, 0.04f);
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x) {
      const glm::vec2 q((float(x) + 0.5f) / kSize, (float(y) + 0.5f) / kSize);
      float* out = &tex.rgba[(std::size_t(y) * kSize + x) * 4];
      bool covered = false;
      glm::vec3 colour(0.0f);
      if (std::abs(q.x - 0.5f) < 0.006f && q.y > twig_to.y && q.y < twig_from.y) {
        covered = true;
        colour = twig_colour;
      }
      for (const Leaf& leaf : leaves) {
        const glm::vec2 d = q - leaf.base;
        const float u = glm::dot(d, leaf.axis) / leaf.length;
        if (u <= 0.0f || u >= 1.0f) continue;
        const float v = glm::dot(d, leaf.side) / leaf.half_width;
        // Pointed leaf outline: widest a little below the middle, sharp at both ends.
        const float outline = std::pow(std::sin(kPi * std::pow(u, 0.8f)), 0.75f);
        if (std::abs(v) >= outline) continue;
        covered = true;
        const float midrib = std::abs(v) < 0.08f ? 1.25f : 1.0f;
        const float towards_tip = 0.85f + 0.3f * u;
        colour = leaf.colour * midrib * towards_tip * (0.9f + 0.2f * std::abs(v));
      }
      if (!covered) continue;
      out[0] = colour.x;
      out[1] = colour.y;
      out[2] = colour.z;
      out[3] = 1.0f;
    }
  return tex;
}

// ---------------------------------------------------------------------------------------------
// Pieces.

// A column standing on `foot` (floor level): square plinth, lathe-turned base moulding, a
// shaft with entasis (a slight taper), a necking ring and a cushion-shaped capital, then a
// square abacus whose top is at foot.y + 4.0.
void append_column(std::vector<SceneTriangle>& tris, glm::vec3 foot, const Tessellation& tess) {
  constexpr float kPlinthTop = 0.2f, kAbacusBottom = 3.85f, kAbacusTop = 4.0f, kHalf = 0.4f;
  append_box(tris, foot + glm::vec3(-kHalf, 0.0f, -kHalf), foot + glm::vec3(kHalf, kPlinthTop, kHalf), kStone);

  std::vector<glm::vec2> profile;  // (radius, height above the plinth)
  const int m = tess.moulding_steps;
  // Torus moulding: a half round of radius 0.06 round a core of radius 0.30.
  for (int i = 0; i <= m; ++i) {
    const float a = -0.5f * kPi + kPi * float(i) / float(m);
    profile.emplace_back(0.30f + 0.06f * std::cos(a), 0.06f + 0.06f * std::sin(a));
  }
  // Shaft with entasis from radius 0.25 to 0.215.
  const float shaft_bottom = 0.12f, shaft_top = 3.40f;
  for (int i = 0; i <= tess.shaft_rings; ++i) {
    const float t = float(i) / float(tess.shaft_rings);
    profile.emplace_back(0.25f - 0.035f * t * t, shaft_bottom + (shaft_top - shaft_bottom) * t);
  }
  // Necking ring (astragal): a small half round.
  for (int i = 1; i < m + 2; ++i) {
    const float a = -0.5f * kPi + kPi * float(i) / float(m + 1);
    profile.emplace_back(0.215f + 0.025f * std::cos(a), shaft_top + 0.025f + 0.025f * std::sin(a));
  }
  // Echinus: cushion flaring out to the abacus.
  const float echinus_bottom = shaft_top + 0.05f, echinus_top = kAbacusBottom - kPlinthTop;
  for (int i = 1; i <= m; ++i) {  // i = 0 is the necking ring's last point
    const float a = 0.5f * kPi * float(i) / float(m);
    profile.emplace_back(0.215f + 0.145f * std::sin(a),
                         echinus_bottom + (echinus_top - echinus_bottom) * (1.0f - std::cos(a)));
  }
  append_lathe(tris, foot + glm::vec3(0.0f, kPlinthTop, 0.0f), profile, tess.column_facets, kStone,
               LatheCaps{false, true});
  append_box(tris, foot + glm::vec3(-kHalf, kAbacusBottom, -kHalf), foot + glm::vec3(kHalf, kAbacusTop, kHalf), kStone);
}

// One bay of the arcade between the column centres c0 and c1 (floor level): a wall of
// thickness 2 * half_depth from the springing height y_spring up to y_top, pierced by a
// semicircular arch whose underside (soffit) is rounded across its depth.
//
// The wall faces are strips of quads from the arch out to the bay's rectangle, radially from
// the arch's centre; the arc is split at the rectangle's top corners so those corners are
// vertices. Arch points are computed by one function so the faces and the soffit share them
// exactly.
void append_arcade_bay(std::vector<SceneTriangle>& tris, glm::vec3 c0, glm::vec3 c1, float y_spring, float y_top,
                       float half_depth, float pier_half_width, const Tessellation& tess) {
  const glm::vec3 along = glm::normalize(glm::vec3(c1.x - c0.x, 0.0f, c1.z - c0.z));
  const glm::vec3 across(-along.z, 0.0f, along.x);
  const float length = glm::length(glm::vec3(c1.x - c0.x, 0.0f, c1.z - c0.z));
  const float half = 0.5f * length;
  const float radius = half - pier_half_width;
  const float rise = y_top - y_spring;
  const float bulge = 0.05f;
  auto at = [&](float s, float y, float depth) {
    return c0 + along * s + across * depth + glm::vec3(0.0f, y - c0.y, 0.0f);
  };

  // Angles from the bay's c1 end (0) over the top to its c0 end (pi), with the rectangle's
  // corners at corner and pi - corner.
  const float corner = std::atan2(rise, half);
  const int n = tess.arch_segments;
  const int n_side = std::max(1, int(std::lround(n * corner / kPi)));
  const int n_top = std::max(1, n - 2 * n_side);
  std::vector<float> angle;
  std::vector<glm::vec2> outer;  // (s, y) on the rectangle, radially outward of each arch point
  for (int i = 0; i <= n_side; ++i) {
    const float a = corner * float(i) / float(n_side);
    angle.push_back(a);
    outer.emplace_back(length, i == n_side ? y_top : y_spring + half * std::tan(a));
  }
  for (int i = 1; i <= n_top; ++i) {
    const float a = corner + (kPi - 2.0f * corner) * float(i) / float(n_top);
    angle.push_back(a);
    outer.emplace_back(i == n_top ? 0.0f : half + rise * std::cos(a) / std::sin(a), y_top);
  }
  for (int i = 1; i <= n_side; ++i) {
    const float a = (kPi - corner) + corner * float(i) / float(n_side);
    angle.push_back(a);
    outer.emplace_back(0.0f, i == n_side ? y_spring : y_spring + half * std::tan(kPi - a));
  }
  const std::size_t count = angle.size();
  std::vector<float> cos_a(count), sin_a(count);
  for (std::size_t i = 0; i < count; ++i) {
    cos_a[i] = std::cos(angle[i]);
    sin_a[i] = std::max(0.0f, std::sin(angle[i]));
  }
  // Exact springing points, so the arch meets the abacus without a sliver.
  cos_a.front() = 1.0f;
  sin_a.front() = 0.0f;
  cos_a.back() = -1.0f;
  sin_a.back() = 0.0f;
  // Soffit point: arch point i at depth strip j (0 and P are the wall faces). The rounding
  // fades out towards the springing (factor sin a), where the soffit meets the flat abacus.
  const int strips = tess.soffit_strips;
  auto soffit = [&](std::size_t i, int j) {
    const float depth = -half_depth + 2.0f * half_depth * float(j) / float(strips);
    const float r =
        (j == 0 || j == strips) ? radius : radius - bulge * sin_a[i] * std::sin(kPi * float(j) / float(strips));
    return at(half + r * cos_a[i], y_spring + r * sin_a[i], depth);
  };

  for (std::size_t i = 0; i + 1 < count; ++i) {
    for (float side : {1.0f, -1.0f}) {
      const int j = side > 0.0f ? strips : 0;
      const float depth = side * half_depth;
      append_quad_facing(tris, soffit(i, j), soffit(i + 1, j), at(outer[i + 1].x, outer[i + 1].y, depth),
                         at(outer[i].x, outer[i].y, depth), across * side, kStone);
    }
    const glm::vec3 axis_point = at(half, y_spring, 0.0f);
    for (int j = 0; j < strips; ++j) {
      const glm::vec3 a = soffit(i, j), b = soffit(i + 1, j), c = soffit(i + 1, j + 1), d = soffit(i, j + 1);
      // Faces the arch's axis, offset to the strip's depth.
      const glm::vec3 centroid = 0.25f * (a + b + c + d);
      const glm::vec3 towards = axis_point + across * glm::dot(centroid - axis_point, across) - centroid;
      append_quad_facing(tris, a, b, c, d, towards, kStone);
    }
  }
}

// A cloud of leaf cards filling the ellipsoid (center, radii): each card a square of about
// `card_size` with random orientation, textured with the whole leaf texture.
void append_foliage(std::vector<SceneTriangle>& tris, GeneratorRng& rng, glm::vec3 center, glm::vec3 radii, int cards,
                    float card_size) {
  for (int i = 0; i < cards; ++i) {
    const glm::vec3 p = center + radii * rng.in_unit_ball();
    const glm::vec3 normal = rng.unit_vector();
    const glm::vec3 helper = std::abs(normal.y) < 0.9f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
    // The card's "up" (texture v) leans upwards, as twigs do, with a random twist.
    const glm::vec3 t0 = glm::normalize(glm::cross(helper, normal));
    const glm::vec3 b0 = glm::cross(normal, t0);
    const float twist = rng.range(-0.8f, 0.8f);
    const glm::vec3 t = std::cos(twist) * t0 + std::sin(twist) * b0;
    const glm::vec3 b = glm::cross(normal, t);
    const float h = 0.5f * card_size * rng.range(0.75f, 1.25f);
    append_quad(tris, p - h * t - h * b, p + h * t - h * b, p + h * t + h * b, p - h * t + h * b, kLeaves);
  }
}

// Open-topped planter box (walls 6 cm thick) filled with soil, centred on `foot`, and a shrub.
void append_planter(std::vector<SceneTriangle>& tris, GeneratorRng& rng, glm::vec3 foot, const Tessellation& tess) {
  const float half = 0.6f, height = 0.6f, wall = 0.06f;
  const glm::vec3 lo = foot + glm::vec3(-half, 0.0f, -half), hi = foot + glm::vec3(half, height, half);
  append_box(tris, lo, {hi.x, hi.y, lo.z + wall}, kTerracotta);
  append_box(tris, {lo.x, lo.y, hi.z - wall}, hi, kTerracotta);
  append_box(tris, {lo.x, lo.y, lo.z + wall}, {lo.x + wall, hi.y, hi.z - wall}, kTerracotta);
  append_box(tris, {hi.x - wall, lo.y, lo.z + wall}, {hi.x, hi.y, hi.z - wall}, kTerracotta);
  append_box(tris, {lo.x + wall, lo.y, lo.z + wall}, {hi.x - wall, height - 0.08f, hi.z - wall}, kSoil);
  const int cards = std::max(12, int(std::lround(3000.0f * tess.foliage_scale)));
  append_foliage(tris, rng, foot + glm::vec3(0.0f, height + 0.55f, 0.0f), {0.85f, 0.6f, 0.85f}, cards, 0.32f);
}

// A tree: tapering trunk and a crown of leaf cards.
void append_tree(std::vector<SceneTriangle>& tris, GeneratorRng& rng, glm::vec3 foot, const Tessellation& tess) {
  const glm::vec2 trunk[] = {{0.22f, 0.0f}, {0.16f, 1.5f}, {0.12f, 3.0f}, {0.0f, 3.3f}};
  append_lathe(tris, foot, trunk, std::max(6, tess.column_facets / 3), kBark);
  const int cards = std::max(24, int(std::lround(22000.0f * tess.foliage_scale)));
  append_foliage(tris, rng, foot + glm::vec3(0.0f, 3.7f, 0.0f), {2.4f, 1.5f, 2.4f}, cards, 0.42f);
}

}  // namespace

Scene make_atrium_scene(const nlohmann::json& params) {
  check_generator_params("atrium", params, {"detail", "seed"});
  const double detail = generator_number("atrium", params, "detail", 1.0, 0.01, 4.0);
  const double seed_value = generator_number("atrium", params, "seed", 1.0, 0.0, 4294967295.0);
  if (seed_value != std::floor(seed_value)) throw SceneError("generator 'atrium': parameter 'seed' must be an integer");
  const auto seed = std::uint64_t(seed_value);
  const Tessellation tess = tessellation_for(detail);

  Scene scene;
  scene.name = "atrium";
  scene.meters_per_unit = 1.0f;
  scene.materials = atrium_materials();
  scene.textures.push_back(make_leaf_texture(seed));
  auto& tris = scene.triangles;
  tris.reserve(std::size_t(620000 * std::pow(detail, 1.5)) + 20000);
  GeneratorRng rng(seed);

  constexpr float W = 32.0f, D = 22.0f;  // courtyard floor [0, W] x [0, D]
  constexpr float kWallHeight = 9.0f, kWallThickness = 0.5f;
  constexpr float x0 = 4.0f, x1 = W - 4.0f, z0 = 4.0f, z1 = D - 4.0f;  // column rectangle
  constexpr float kSpring = 4.0f, kArcadeTop = 6.0f, kArcadeHalfDepth = 0.3f, kPierHalf = 0.4f;

  append_quad(tris, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, D}, {W, 0.0f, D}, {W, 0.0f, 0.0f}, kFloor,
              {glm::vec2(0, 0), glm::vec2(0, D), glm::vec2(W, D), glm::vec2(W, 0)});
  const float t = kWallThickness;
  append_box(tris, {-t, 0.0f, -t}, {0.0f, kWallHeight, D + t}, kWall);
  append_box(tris, {W, 0.0f, -t}, {W + t, kWallHeight, D + t}, kWall);
  append_box(tris, {0.0f, 0.0f, -t}, {W, kWallHeight, 0.0f}, kWall);
  append_box(tris, {0.0f, 0.0f, D}, {W, kWallHeight, D + t}, kWall);

  // Columns: 9 along each long side (3 m bays), 5 along each short side (3.5 m bays), corners
  // shared. Listed round the rectangle so consecutive entries of a side form the bays.
  const int long_count = 9, short_count = 5;
  std::vector<glm::vec3> south, north, west, east;
  for (int i = 0; i < long_count; ++i) {
    const float x = x0 + (x1 - x0) * float(i) / float(long_count - 1);
    south.emplace_back(x, 0.0f, z0);
    north.emplace_back(x, 0.0f, z1);
  }
  for (int i = 0; i < short_count; ++i) {
    const float z = z0 + (z1 - z0) * float(i) / float(short_count - 1);
    west.emplace_back(x0, 0.0f, z);
    east.emplace_back(x1, 0.0f, z);
  }
  for (const glm::vec3& c : south) append_column(tris, c, tess);
  for (const glm::vec3& c : north) append_column(tris, c, tess);
  for (int i = 1; i + 1 < short_count; ++i) {
    append_column(tris, west[i], tess);
    append_column(tris, east[i], tess);
  }
  for (const auto* side : {&south, &north, &west, &east})
    for (std::size_t i = 0; i + 1 < side->size(); ++i)
      append_arcade_bay(tris, (*side)[i], (*side)[i + 1], kSpring, kArcadeTop, kArcadeHalfDepth, kPierHalf, tess);
  // Solid piers above the corner columns, where two arcades meet.
  for (const glm::vec3& c : {south.front(), south.back(), north.front(), north.back()})
    append_box(tris, c + glm::vec3(-kPierHalf, kSpring, -kPierHalf), c + glm::vec3(kPierHalf, kArcadeTop, kPierHalf),
               kStone);
  // Cornice along the arcades and the portico roof out to the walls.
  constexpr float kCorniceTop = 6.4f, kCorniceHalf = 0.45f, kRoofTop = 6.25f;
  append_box(tris, {x0 - kCorniceHalf, kArcadeTop, z0 - kCorniceHalf},
             {x1 + kCorniceHalf, kCorniceTop, z0 + kCorniceHalf}, kStone);
  append_box(tris, {x0 - kCorniceHalf, kArcadeTop, z1 - kCorniceHalf},
             {x1 + kCorniceHalf, kCorniceTop, z1 + kCorniceHalf}, kStone);
  append_box(tris, {x0 - kCorniceHalf, kArcadeTop, z0 + kCorniceHalf},
             {x0 + kCorniceHalf, kCorniceTop, z1 - kCorniceHalf}, kStone);
  append_box(tris, {x1 - kCorniceHalf, kArcadeTop, z0 + kCorniceHalf},
             {x1 + kCorniceHalf, kCorniceTop, z1 - kCorniceHalf}, kStone);
  append_box(tris, {0.0f, kArcadeTop, 0.0f}, {W, kRoofTop, z0}, kWall);
  append_box(tris, {0.0f, kArcadeTop, z1}, {W, kRoofTop, D}, kWall);
  append_box(tris, {0.0f, kArcadeTop, z0}, {x0, kRoofTop, z1}, kWall);
  append_box(tris, {x1, kArcadeTop, z0}, {W, kRoofTop, z1}, kWall);

  // Podium: three steps of 18 cm rise and 40 cm tread round a 6.4 x 4.4 m top; a tree on it.
  const glm::vec3 centre(0.5f * W, 0.0f, 0.5f * D);
  constexpr int kSteps = 3;
  constexpr float kRise = 0.18f, kTread = 0.4f;
  for (int i = 0; i < kSteps; ++i) {
    const float hx = 4.0f - kTread * float(i), hz = 3.0f - kTread * float(i);
    append_box(tris, centre + glm::vec3(-hx, kRise * float(i), -hz), centre + glm::vec3(hx, kRise * float(i + 1), hz),
               kPodium);
  }
  append_tree(tris, rng, centre + glm::vec3(0.0f, kRise * kSteps, 0.0f), tess);
  for (const glm::vec2 p : {glm::vec2(7.5f, 7.5f), glm::vec2(7.5f, 14.5f), glm::vec2(24.5f, 7.5f),
                            glm::vec2(24.5f, 14.5f), glm::vec2(16.0f, 5.6f), glm::vec2(16.0f, 16.4f)})
    append_planter(tris, rng, {p.x, 0.0f, p.y}, tess);

  scene.sun.enabled = true;
  scene.sun.direction = glm::normalize(glm::vec3(-0.45f, 0.75f, 0.35f));
  scene.sun.radiance = glm::vec3(2000.0f, 1900.0f, 1700.0f) * 55.0f;
  scene.sun.angular_radius_deg = 0.27f;
  scene.sky.enabled = true;
  scene.sky.zenith = {0.3f, 0.5f, 1.0f};
  scene.sky.horizon = {0.8f, 0.85f, 0.9f};
  scene.sky.ground = {0.25f, 0.22f, 0.18f};

  // A walk at eye height: down the south portico, out through a bay of the arcade, round the
  // podium. Keys keep at least half a metre from every column, planter and shrub.
  constexpr float kEye = 1.7f;
  const glm::vec3 tree(centre.x, 2.5f, centre.z);
  scene.camera_path = {
      {0.0f, {2.5f, kEye, 2.0f}, {14.0f, kEye, 2.0f}},
      {3.0f, {9.0f, kEye, 2.0f}, {16.0f, kEye, 3.0f}},
      {4.5f, {11.5f, kEye, 3.0f}, {12.5f, 2.0f, 8.0f}},
      {6.0f, {11.5f, kEye, 6.0f}, tree},
      {8.5f, {9.5f, kEye, 11.0f}, tree},
      {11.0f, {11.5f, kEye, 14.9f}, tree},
      {13.5f, {19.5f, kEye, 14.9f}, tree},
      {16.0f, {23.0f, kEye, 11.0f}, {16.0f, 3.5f, 8.0f}},
  };
  scene.camera.position = scene.camera_path.front().position;
  scene.camera.target = scene.camera_path.front().target;
  scene.camera.up = {0.0f, 1.0f, 0.0f};
  scene.camera.vfov_deg = 60.0f;
  return scene;
}

}  // namespace px
