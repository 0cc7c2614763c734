// Scenes that move: keyframe sampling against values worked out by hand, glTF node animation
// and skinning against an evaluation written here independently of the loader, the per-frame
// device update against a fresh upload of the same pose, N devices bit-identical with
// animation playing, and the motion pass against a quad's analytic motion.
#include "app/commands.h"
#include "app/scene_setup.h"
#include "bvh/bvh_builder.h"
#include "bvh/bvh_layout.h"
#include "bvh/bvh_refit.h"
#include "bvh/bvh_validator.h"
#include "bvh/flat_bvh.h"
#include "bvh/scene_bvhs.h"
#include "bvh/top_level_bvh.h"
#include "bvh/wide_bvh.h"
#include "cl/launch.h"
#include "pipeline/stereo_pipeline.h"
#include "render/device_scene.h"
#include "render/path_tracer.h"
#include "render/scene_animator.h"
#include "render/stereo_camera.h"
#include "scene/animation.h"
#include "scene/instancing.h"
#include "scene/primitives.h"
#include "scene/scene_loader.h"
#include "scene/scene_rig.h"
#include "scene/sun_path.h"
#include "support/gltf_builder.h"
#include "support/test_support.h"

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <numbers>
#include <random>

namespace px {
namespace {

using nlohmann::json;
using test::GltfBuilder;
using test::TempDir;

constexpr double kPi = std::numbers::pi;

// ---- keyframes ----

KeyframeTrack track(std::vector<double> times, std::vector<glm::dvec4> values, Interpolation i) {
  KeyframeTrack t;
  t.times = std::move(times);
  t.values = std::move(values);
  t.interpolation = i;
  return t;
}

// A static mesh's last copy is turned to world space in its own arrays (emit_last_copy) instead of
// beside them (emit_primitive): the same triangles, bit for bit, and the same drops, whatever the
// transform (a mirror turns the winding), with a normal that degenerates, a non-finite uv, a
// degenerate triangle and vertex colours.
TEST(SceneRig, ALastCopyMadeInPlaceIsTheCopyMadeBesideIt) {
  RigPrimitive prim;
  const int n = 12;
  for (int z = 0; z <= n; ++z)
    for (int x = 0; x <= n; ++x) {
      prim.positions.push_back({0.3f * x - 1.7f, 0.11f * std::sin(1.3f * x) * std::cos(0.7f * z), 0.29f * z + 0.1f});
      prim.normals.push_back(glm::normalize(glm::vec3(0.2f * std::cos(1.1f * x), 1.0f, -0.3f * std::sin(0.9f * z))));
      prim.uvs.push_back({x / float(n), 1.0f - z / float(n) * 0.75f});
      prim.colours.push_back({x / float(n), 0.5f, z / float(n)});
    }
  prim.normals[5] = glm::vec3(0.0f);                                       // its corners take the geometric normal
  prim.uvs[7] = glm::vec2(std::numeric_limits<float>::quiet_NaN(), 0.5f);  // zero
  for (std::uint32_t z = 0; z < std::uint32_t(n); ++z)
    for (std::uint32_t x = 0; x < std::uint32_t(n); ++x) {
      const std::uint32_t a = z * (n + 1) + x, b = a + 1, c = a + n + 1, d = c + 1;
      prim.triangles.push_back({a, c, b});
      prim.triangles.push_back({b, c, d});
    }
  prim.triangles.push_back({0, 0, 1});  // degenerate: dropped by both
  prim.material = 2;
  const glm::dmat4 turned = glm::scale(
      glm::rotate(glm::translate(glm::dmat4(1.0), glm::dvec3(0.4, -2.0, 3.5)), 0.7, glm::dvec3(0.3, 1.0, -0.2)),
      glm::dvec3(1.5, 0.25, 2.0));
  const glm::dmat4 mirrored = glm::scale(turned, glm::dvec3(-1.0, 1.0, 1.0));
  for (const glm::dmat4& world : {glm::dmat4(1.0), turned, mirrored}) {
    std::vector<SceneTriangle> beside, in_place;
    std::vector<std::array<glm::vec3, 3>> colours_beside, colours_in_place;
    SceneStats stats_beside, stats_in_place;
    emit_primitive(prim, world, nullptr, nullptr, nullptr, beside, stats_beside, &colours_beside);
    RigPrimitive consumed = prim;
    emit_last_copy(consumed, world, in_place, stats_in_place, &colours_in_place);
    ASSERT_EQ(beside.size(), prim.triangles.size() - 1);
    ASSERT_EQ(in_place.size(), beside.size());
    EXPECT_EQ(std::memcmp(in_place.data(), beside.data(), beside.size() * sizeof(SceneTriangle)), 0);
    ASSERT_EQ(colours_in_place.size(), colours_beside.size());
    EXPECT_EQ(
        std::memcmp(colours_in_place.data(), colours_beside.data(), colours_beside.size() * sizeof(colours_beside[0])),
        0);
    EXPECT_EQ(stats_in_place.dropped_degenerate, 1u);
    EXPECT_EQ(stats_beside.dropped_degenerate, 1u);
    // It did turn the primitive's own vertices (that is where the memory is saved).
    EXPECT_EQ(consumed.positions[0], in_place[0].p[0]) << "triangle 0 begins at vertex 0";
  }
}

// A primitive of 2^18 triangles or more is made on every core (each core its own range, the
// room for them made first): the same triangles, drops, colours and order as the same primitive
// made in pieces small enough to go one triangle at a time, for static copies (dropping), the
// last copy made in place, and a pose's kept triangles (keeping every one).
TEST(SceneRig, ALargePrimitiveMadeInPartsIsTheOneMadeInSmallPieces) {
  RigPrimitive prim;
  const int n = 370;  // 273,800 triangles
  for (int z = 0; z <= n; ++z)
    for (int x = 0; x <= n; ++x) {
      prim.positions.push_back({0.01f * x, 0.05f * std::sin(0.3f * x) * std::cos(0.2f * z), 0.01f * z});
      prim.normals.push_back(glm::normalize(glm::vec3(0.2f * std::cos(0.1f * x), 1.0f, -0.3f * std::sin(0.09f * z))));
      prim.uvs.push_back({x / float(n), z / float(n)});
      prim.colours.push_back({x / float(n), 0.5f, z / float(n)});
    }
  prim.normals[1000] = glm::vec3(0.0f);                               // its corners take the geometric normal
  prim.positions[90000].y = std::numeric_limits<float>::quiet_NaN();  // its six triangles: non-finite
  for (std::uint32_t z = 0; z < std::uint32_t(n); ++z)
    for (std::uint32_t x = 0; x < std::uint32_t(n); ++x) {
      const std::uint32_t a = z * (n + 1) + x, b = a + 1, c = a + n + 1, d = c + 1;
      prim.triangles.push_back({a, c, b});
      prim.triangles.push_back({b, c, d});
    }
  for (std::uint32_t k = 0; k < 40; ++k) prim.triangles[7 * k + 3] = {k, k, k + 1};  // degenerate
  prim.material = 1;
  ASSERT_GE(prim.triangles.size(), std::size_t{1} << 18);
  // The same primitive in pieces of 50k triangles (made one by one), appended in order.
  const auto in_pieces = [&](const RigPrimitive& whole, const glm::dmat4& world, const std::vector<std::uint32_t>* kept,
                             std::vector<SceneTriangle>& out, SceneStats& stats,
                             std::vector<std::array<glm::vec3, 3>>& colours) {
    const std::size_t piece = 50000;
    if (kept) {
      for (std::size_t i = 0; i < kept->size(); i += piece) {
        const std::vector<std::uint32_t> part(kept->begin() + std::ptrdiff_t(i),
                                              kept->begin() + std::ptrdiff_t(std::min(kept->size(), i + piece)));
        emit_primitive(whole, world, nullptr, &part, nullptr, out, stats, &colours);
      }
      return;
    }
    for (std::size_t i = 0; i < whole.triangles.size(); i += piece) {
      RigPrimitive part = whole;
      part.triangles.assign(whole.triangles.begin() + std::ptrdiff_t(i),
                            whole.triangles.begin() + std::ptrdiff_t(std::min(whole.triangles.size(), i + piece)));
      emit_primitive(part, world, nullptr, nullptr, nullptr, out, stats, &colours);
    }
  };
  const auto same = [](const std::vector<SceneTriangle>& a, const std::vector<SceneTriangle>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(SceneTriangle)) == 0;
  };
  const glm::dmat4 mirrored =
      glm::scale(glm::translate(glm::dmat4(1.0), glm::dvec3(0.4, -2.0, 3.5)), glm::dvec3(-1.5, 0.5, 2.0));
  for (const glm::dmat4& world : {glm::dmat4(1.0), mirrored}) {
    std::vector<SceneTriangle> whole, pieces, in_place;
    std::vector<std::array<glm::vec3, 3>> whole_colours, piece_colours, in_place_colours;
    SceneStats whole_stats, piece_stats, in_place_stats;
    whole.push_back(SceneTriangle{});  // appended after what the array held
    pieces.push_back(SceneTriangle{});
    emit_primitive(prim, world, nullptr, nullptr, nullptr, whole, whole_stats, &whole_colours);
    in_pieces(prim, world, nullptr, pieces, piece_stats, piece_colours);
    EXPECT_EQ(whole.size(), 1 + prim.triangles.size() - 40 - 6);
    EXPECT_TRUE(same(whole, pieces));
    EXPECT_EQ(whole_colours, piece_colours);
    EXPECT_EQ(whole_stats.dropped_degenerate, 40u);
    EXPECT_EQ(whole_stats.dropped_nonfinite, 6u);
    EXPECT_EQ(piece_stats.dropped_degenerate, 40u);
    EXPECT_EQ(piece_stats.dropped_nonfinite, 6u);
    RigPrimitive consumed = prim;
    in_place.push_back(SceneTriangle{});
    emit_last_copy(consumed, world, in_place, in_place_stats, &in_place_colours);
    EXPECT_TRUE(same(in_place, pieces));
    EXPECT_EQ(in_place_colours, piece_colours);
    // A pose's kept triangles: every one, the non-finite and degenerate ones too.
    std::vector<std::uint32_t> kept(prim.triangles.size());
    for (std::size_t k = 0; k < kept.size(); ++k) kept[k] = std::uint32_t(kept.size() - 1 - k);
    std::vector<SceneTriangle> posed, posed_pieces;
    std::vector<std::array<glm::vec3, 3>> posed_colours, posed_piece_colours;
    SceneStats posed_stats, posed_piece_stats;
    emit_primitive(prim, world, nullptr, &kept, nullptr, posed, posed_stats, &posed_colours);
    in_pieces(prim, world, &kept, posed_pieces, posed_piece_stats, posed_piece_colours);
    EXPECT_EQ(posed.size(), kept.size());
    EXPECT_TRUE(same(posed, posed_pieces));
    EXPECT_EQ(posed_colours, posed_piece_colours);
  }
}

TEST(KeyframeTrack, StepAndLinearMatchHandValues) {
  const KeyframeTrack step =
      track({1.0, 2.0, 4.0}, {{0, 0, 0, 0}, {10, 20, 30, 0}, {-4, 0, 4, 0}}, Interpolation::Step);
  EXPECT_EQ(sample_track(step, 0.0, false), glm::dvec4(0, 0, 0, 0));  // before the first key: hold it
  EXPECT_EQ(sample_track(step, 1.999, false), glm::dvec4(0, 0, 0, 0));
  EXPECT_EQ(sample_track(step, 2.0, false), glm::dvec4(10, 20, 30, 0));
  EXPECT_EQ(sample_track(step, 3.9, false), glm::dvec4(10, 20, 30, 0));
  EXPECT_EQ(sample_track(step, 9.0, false), glm::dvec4(-4, 0, 4, 0));  // after the last: hold it
  KeyframeTrack linear = step;
  linear.interpolation = Interpolation::Linear;
  const glm::dvec4 a = sample_track(linear, 1.25, false);  // a quarter of the way from key 0 to key 1
  EXPECT_DOUBLE_EQ(a.x, 2.5);
  EXPECT_DOUBLE_EQ(a.y, 5.0);
  EXPECT_DOUBLE_EQ(a.z, 7.5);
  const glm::dvec4 b = sample_track(linear, 3.0, false);  // half way from key 1 to key 2
  EXPECT_DOUBLE_EQ(b.x, 3.0);
  EXPECT_DOUBLE_EQ(b.y, 10.0);
  EXPECT_DOUBLE_EQ(b.z, 17.0);
  EXPECT_EQ(sample_track(linear, 2.0, false), glm::dvec4(10, 20, 30, 0));  // exactly a key's value at its time
}

TEST(KeyframeTrack, CubicSplineMatchesTheHermiteFormWorkedByHand) {
  // Keys at 0 and 2 with values 0 and 1; key 0's out-tangent 1, key 1's in-tangent 0 (other
  // tangents are never used between these keys). At t = 1: s = 0.5, interval 2,
  //   p = h00(s) 0 + h10(s) 2 x 1 + h01(s) 1 + h11(s) 2 x 0
  //     = 0 + (0.125 - 0.5 + 0.5) x 2 + (-0.25 + 0.75) = 0.25 + 0.5 = 0.75.
  const KeyframeTrack t = track({0.0, 2.0},
                                {{99, 0, 0, 0},
                                 {0, 0, 0, 0},
                                 {1, 0, 0, 0},  // key 0: in, value, out
                                 {0, 0, 0, 0},
                                 {1, 0, 0, 0},
                                 {99, 0, 0, 0}},  // key 1
                                Interpolation::CubicSpline);
  EXPECT_NEAR(sample_track(t, 1.0, false).x, 0.75, 1e-12);
  // s = 0.25: h00 = 0.84375, h10 = 0.140625, h01 = 0.15625, h11 = -0.046875:
  // 0.140625 x 2 + 0.15625 = 0.4375.
  EXPECT_NEAR(sample_track(t, 0.5, false).x, 0.4375, 1e-12);
  EXPECT_EQ(sample_track(t, 0.0, false).x, 0.0);
  EXPECT_EQ(sample_track(t, 2.0, false).x, 1.0);
}

glm::dvec4 axis_angle(glm::dvec3 axis, double angle) {  // (x, y, z, w) as glTF stores it
  axis = glm::normalize(axis);
  return glm::dvec4(axis * std::sin(angle / 2), std::cos(angle / 2));
}

TEST(KeyframeTrack, RotationsSlerpAlongTheShorterArc) {
  const glm::dvec3 y(0, 1, 0);
  const KeyframeTrack t = track({0.0, 1.0}, {axis_angle(y, 0.0), axis_angle(y, kPi / 2)}, Interpolation::Linear);
  // Slerp turns at a constant rate: a third of the time, a third of the angle.
  const glm::dvec4 q = sample_track(t, 1.0 / 3.0, true);
  const glm::dvec4 want = axis_angle(y, kPi / 6);
  for (int c = 0; c < 4; ++c) EXPECT_NEAR(q[c], want[c], 1e-12) << c;
  // The same end rotation stored as -q: still the 30 degree turn, not the long way round.
  const KeyframeTrack neg = track({0.0, 1.0}, {axis_angle(y, 0.0), -axis_angle(y, kPi / 2)}, Interpolation::Linear);
  const glm::dvec4 r = sample_track(neg, 1.0 / 3.0, true);
  for (int c = 0; c < 4; ++c) EXPECT_NEAR(std::abs(r[c]), std::abs(want[c]), 1e-12) << c;
  EXPECT_NEAR(std::abs(r.w), std::cos(kPi / 12), 1e-12);
  // A cubic rotation comes back normalised.
  const KeyframeTrack cubic =
      track({0.0, 1.0},
            {glm::dvec4(0), axis_angle(y, 0.0), glm::dvec4(0), glm::dvec4(0), axis_angle(y, kPi / 2), glm::dvec4(0)},
            Interpolation::CubicSpline);
  EXPECT_NEAR(glm::length(sample_track(cubic, 0.4, true)), 1.0, 1e-12);
}

TEST(AnimationClip, LoopsOverItsLengthAndSelectsByNameOrIndex) {
  AnimationClip clip;
  clip.duration = 2.0;
  EXPECT_DOUBLE_EQ(clip_time(clip, 0.5), 0.5);
  EXPECT_DOUBLE_EQ(clip_time(clip, 5.0), 1.0);
  EXPECT_DOUBLE_EQ(clip_time(clip, -0.5), 1.5);
  AnimationClip still;  // zero length: always its start
  EXPECT_EQ(clip_time(still, 3.0), 0.0);

  std::vector<AnimationClip> clips(3);
  clips[0].name = "walk";
  clips[1].name = "run";
  clips[2].name = "2";
  EXPECT_EQ(select_clips(clips, "all"), (std::vector<int>{0, 1, 2}));
  EXPECT_TRUE(select_clips(clips, "none").empty());
  EXPECT_EQ(select_clips(clips, "run"), (std::vector<int>{1}));
  EXPECT_EQ(select_clips(clips, "2"), (std::vector<int>{2}));  // a name wins over an index
  EXPECT_EQ(select_clips(clips, "0"), (std::vector<int>{0}));
  try {
    select_clips(clips, "jump");
    ADD_FAILURE() << "no error for a clip that does not exist";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'walk'"), std::string::npos) << e.what();
  }
}

// ---- glTF ----

// A unit cube (-0.5..0.5) as 12 triangles, positions only.
void add_cube_mesh(GltfBuilder& g, int material = -1) {
  std::vector<float> p;
  for (int i = 0; i < 8; ++i) {
    p.push_back((i & 1) ? 0.5f : -0.5f);
    p.push_back((i & 2) ? 0.5f : -0.5f);
    p.push_back((i & 4) ? 0.5f : -0.5f);
  }
  const std::vector<std::uint16_t> idx = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                                          2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
  json prim = {{"attributes", {{"POSITION", g.floats(p, "VEC3", 8)}}}, {"indices", g.uint16s(idx, "SCALAR", 36)}};
  if (material >= 0) prim["material"] = material;
  g.add("meshes", {{"primitives", json::array({prim})}});
}

struct Bounds {
  glm::vec3 lo{1e30f}, hi{-1e30f};
};
Bounds bounds_of(const std::vector<SceneTriangle>& tris) {
  Bounds b;
  for (const auto& t : tris)
    for (const auto& p : t.p) {
      b.lo = glm::min(b.lo, p);
      b.hi = glm::max(b.hi, p);
    }
  return b;
}

// A parent at (0, 3, 0) whose child cube slides from x = 0 to x = 2 and turns 90 degrees about
// z over one second (LINEAR), then loops.
std::string moving_cube_file(const TempDir& dir) {
  GltfBuilder g;
  add_cube_mesh(g);
  const int times = g.floats({0.0f, 1.0f}, "SCALAR", 2);
  const int moves = g.floats({0, 0, 0, 2, 0, 0}, "VEC3", 2);
  const float h = float(std::sqrt(0.5));
  const int turns = g.floats({0, 0, 0, 1, 0, 0, h, h}, "VEC4", 2);
  g.doc["scene"] = 0;
  g.doc["scenes"] = json::array({{{"nodes", {0}}}});
  g.doc["nodes"] = json::array({{{"translation", {0, 3, 0}}, {"children", {1}}}, {{"mesh", 0}}});
  g.doc["animations"] = json::array(
      {{{"name", "slide"},
        {"samplers", json::array({{{"input", times}, {"output", moves}}, {{"input", times}, {"output", turns}}})},
        {"channels", json::array({{{"sampler", 0}, {"target", {{"node", 1}, {"path", "translation"}}}},
                                  {{"sampler", 1}, {"target", {{"node", 1}, {"path", "rotation"}}}}})}}});
  return dir.write("moving.gltf", g.text()).string();
}

TEST(GltfAnimation, ARotatingTranslatingNodeHasTheWorldBoundsWorkedByHand) {
  const TempDir dir;
  Scene scene = load_gltf(moving_cube_file(dir));
  ASSERT_TRUE(scene.rig);
  for (const auto& w : scene.stats.warnings) EXPECT_EQ(w.find("animations"), std::string::npos) << w;
  SceneAnimator animator(scene, "all");
  ASSERT_TRUE(animator.moves());
  // At time t (looped over 1 s): the cube turned by a = 90 t degrees about z is
  // 0.5 (|cos a| + |sin a|) wide either side in x and y, 0.5 in z, centred at (2 t, 3, 0).
  for (double t : {0.0, 0.5, 1.25, 0.9}) {
    animator.pose(t);
    const double u = std::fmod(t, 1.0), a = u * kPi / 2;
    const double half = 0.5 * (std::abs(std::cos(a)) + std::abs(std::sin(a)));
    // The cube is drawn as an instance (a rigid mesh on a moving node): its world triangles
    // are the flat copy's.
    Scene flat = scene;
    flatten_instances(flat);
    const Bounds b = bounds_of(flat.triangles);
    EXPECT_NEAR(b.lo.x, 2 * u - half, 1e-5) << t;
    EXPECT_NEAR(b.hi.x, 2 * u + half, 1e-5) << t;
    EXPECT_NEAR(b.lo.y, 3 - half, 1e-5) << t;
    EXPECT_NEAR(b.hi.y, 3 + half, 1e-5) << t;
    EXPECT_NEAR(b.lo.z, -0.5, 1e-6) << t;
    EXPECT_NEAR(b.hi.z, 0.5, 1e-6) << t;
    EXPECT_EQ(flat.triangles.size(), 12u);
  }
  // --animation none: the rest pose as loaded (the child's own transform: identity).
  Scene rest = load_gltf(moving_cube_file(dir));
  SceneAnimator none(rest, "none");
  EXPECT_FALSE(none.moves());
  none.pose(0.5);
  flatten_instances(rest);
  EXPECT_NEAR(bounds_of(rest.triangles).hi.x, 0.5, 1e-6);
  EXPECT_THROW(SceneAnimator(rest, "jump"), std::invalid_argument);
}

// A file without a camera is framed on where its clips take it, not only on its rest pose: the
// sliding cube stays inside the framed view (45 degrees vertically, square or wider) all along.
TEST(GltfAnimation, AFileWithoutACameraIsFramedOnEverywhereItsClipsGo) {
  const TempDir dir;
  const std::string file = moving_cube_file(dir);
  Scene scene = load_scene(file);
  const Camera cam = scene.camera;
  const glm::vec3 axis = glm::normalize(cam.target - cam.position);
  const double half_angle = 0.5 * double(cam.vfov_deg) * kPi / 180.0;
  SceneAnimator animator(scene, "all");
  double widest = 0.0;
  for (double t : {0.0, 0.25, 0.5, 0.75, 0.99}) {
    animator.pose(t);
    Scene flat = scene;
    flatten_instances(flat);
    for (const SceneTriangle& tri : flat.triangles)
      for (const glm::vec3& p : tri.p) {
        const double angle = std::acos(std::clamp(double(glm::dot(glm::normalize(p - cam.position), axis)), -1.0, 1.0));
        widest = std::max(widest, angle);
        EXPECT_LE(angle, half_angle) << "t = " << t << ": a corner of the cube leaves the view";
      }
  }
  // The rest pose alone (the cube at x 0) would have been framed tighter: the cube at x 2 would
  // then have left the view. The framing is not just wide: the cube fills a fair part of it.
  EXPECT_GT(widest, 0.5 * half_angle);
}

// The glTF specification requires non-negative key times: a file with one is refused, with the
// channel named; the same file with its keys shifted to start at 0 loads and plays.
TEST(GltfAnimation, ANegativeKeyTimeIsRefusedNamingTheChannel) {
  const TempDir dir;
  const auto file_with_keys = [&](const std::string& name, float first, float last) {
    GltfBuilder g;
    add_cube_mesh(g);
    const int times = g.floats({first, last}, "SCALAR", 2);
    const int still = g.floats({0, 0, 0, 0, 0, 0}, "VEC3", 2);
    const int moves = g.floats({0, 0, 0, 2, 0, 0}, "VEC3", 2);
    g.doc["scene"] = 0;
    g.doc["scenes"] = json::array({{{"nodes", {0}}}});
    g.doc["nodes"] = json::array({{{"mesh", 0}}});
    g.doc["animations"] = json::array(
        {{{"samplers", json::array({{{"input", g.floats({0.0f, 1.0f}, "SCALAR", 2)}, {"output", still}},
                                    {{"input", times}, {"output", moves}}})},
          {"channels", json::array({{{"sampler", 0}, {"target", {{"node", 0}, {"path", "scale"}}}},
                                    {{"sampler", 1}, {"target", {{"node", 0}, {"path", "translation"}}}}})}}});
    return dir.write(name, g.text()).string();
  };
  std::string message;
  try {
    load_gltf(file_with_keys("early.gltf", -0.5f, 1.0f));
  } catch (const std::exception& e) {
    message = e.what();
  }
  EXPECT_NE(message.find("early.gltf"), std::string::npos) << message;
  EXPECT_NE(message.find("animation 0 channel 1"), std::string::npos) << message;
  EXPECT_NE(message.find("negative"), std::string::npos) << message;
  Scene ok = load_gltf(file_with_keys("from_zero.gltf", 0.0f, 1.5f));
  ASSERT_TRUE(ok.rig);
  SceneAnimator animator(ok, "all");
  EXPECT_TRUE(animator.moves());
}

// A glTF camera on an animated node follows it; one a scene file placed does not.
TEST(GltfAnimation, ACameraOnAnAnimatedNodeFollowsIt) {
  GltfBuilder g;
  add_cube_mesh(g);
  const int times = g.floats({0.0f, 1.0f}, "SCALAR", 2);
  const int moves = g.floats({0, 0, 5, 4, 0, 5}, "VEC3", 2);
  g.add("cameras", {{"type", "perspective"}, {"perspective", {{"yfov", 0.8}, {"znear", 0.1}}}});
  g.doc["scene"] = 0;
  g.doc["scenes"] = json::array({{{"nodes", {0, 1}}}});
  g.doc["nodes"] = json::array({{{"mesh", 0}}, {{"camera", 0}, {"translation", {0, 0, 5}}}});
  g.doc["animations"] = json::array(
      {{{"samplers", json::array({{{"input", times}, {"output", moves}}})},
        {"channels", json::array({{{"sampler", 0}, {"target", {{"node", 1}, {"path", "translation"}}}}})}}});
  const TempDir dir;
  const std::string file = dir.write("dolly.gltf", g.text()).string();
  Scene scene = load_scene(file);
  SceneAnimator animator(scene, "all");
  ASSERT_TRUE(animator.moves());
  animator.pose(0.25);
  EXPECT_NEAR(scene.camera.position.x, 1.0f, 1e-6);
  EXPECT_NEAR(scene.camera.target.x, 1.0f, 1e-6);  // still looking down -z
  EXPECT_NEAR(scene.camera.target.z, 4.0f, 1e-6);
  // A scene file's camera stays where the file put it.
  const std::string json_file =
      dir.write("placed.json", R"({"mesh": "dolly.gltf", "camera": {"position": [9, 1, 9], "target": [0, 0, 0]}})")
          .string();
  Scene placed = load_scene(json_file);
  SceneAnimator(placed, "all").pose(0.25);
  EXPECT_EQ(placed.camera.position, glm::vec3(9, 1, 9));
}

// Two joints along y: joint 0 at the origin, joint 1 (its child) at (0, 1, 0), turning 90
// degrees about z over one second. A strip of quads from y = 0 to 2 bound to them: y = 0 to
// joint 0 alone, y = 1 half and half, y = 2 to joint 1 alone. The mesh's own node is moved
// by (5, 0, 0), which a skinned mesh ignores.
TEST(GltfAnimation, SkinnedVerticesMatchABruteForceEvaluation) {
  GltfBuilder g;
  const std::vector<float> pos = {-0.5f, 0, 0, 0.5f, 0, 0, -0.5f, 1, 0, 0.5f, 1, 0, -0.5f, 2, 0, 0.5f, 2, 0};
  const std::vector<std::uint16_t> idx = {0, 1, 3, 0, 3, 2, 2, 3, 5, 2, 5, 4};
  const std::vector<std::uint16_t> joints = {0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0};
  const std::vector<float> weights = {1,    0,    0, 0, 1, 0, 0, 0, 0.5f, 0.5f, 0, 0,
                                      0.5f, 0.5f, 0, 0, 0, 1, 0, 0, 0,    1,    0, 0};
  // Inverse bind matrices (column-major): identity, and a translation by (0, -1, 0).
  const std::vector<float> ibm = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0,  0, 1,
                                  1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -1, 0, 1};
  json attrs = {{"POSITION", g.floats(pos, "VEC3", 6)},
                {"JOINTS_0", g.uint16s(joints, "VEC4", 6)},
                {"WEIGHTS_0", g.floats(weights, "VEC4", 6)}};
  g.add("meshes", {{"primitives", json::array({{{"attributes", attrs}, {"indices", g.uint16s(idx, "SCALAR", 12)}}})}});
  const int times = g.floats({0.0f, 1.0f}, "SCALAR", 2);
  const float h = float(std::sqrt(0.5));
  const int turns = g.floats({0, 0, 0, 1, 0, 0, h, h}, "VEC4", 2);
  g.doc["scene"] = 0;
  g.doc["scenes"] = json::array({{{"nodes", {0, 2}}}});
  g.doc["nodes"] = json::array(
      {{{"children", {1}}}, {{"translation", {0, 1, 0}}}, {{"mesh", 0}, {"skin", 0}, {"translation", {5, 0, 0}}}});
  g.doc["skins"] = json::array({{{"joints", {0, 1}}, {"inverseBindMatrices", g.floats(ibm, "MAT4", 2)}}});
  g.doc["animations"] =
      json::array({{{"samplers", json::array({{{"input", times}, {"output", turns}}})},
                    {"channels", json::array({{{"sampler", 0}, {"target", {{"node", 1}, {"path", "rotation"}}}}})}}});
  const TempDir dir;
  Scene scene = load_gltf(dir.write("skin.gltf", g.text()).string());
  ASSERT_TRUE(scene.rig);
  for (const auto& w : scene.stats.warnings) EXPECT_EQ(w.find("skins"), std::string::npos) << w;
  ASSERT_EQ(scene.triangles.size(), 4u);
  SceneAnimator animator(scene, "all");
  for (double t : {0.0, 0.3, 0.5, 0.75}) {
    animator.pose(t);
    // By hand: joint 1's world matrix is T(0, 1, 0) R_z(90 t); joint 0's the identity. Vertex
    // v moves by sum_j w_j (J_j IBM_j) v.
    const double a = t * kPi / 2;
    const glm::dmat4 j1 = glm::rotate(glm::translate(glm::dmat4(1.0), glm::dvec3(0, 1, 0)), a, glm::dvec3(0, 0, 1));
    const glm::dmat4 m1 = j1 * glm::translate(glm::dmat4(1.0), glm::dvec3(0, -1, 0));
    for (std::size_t k = 0; k < idx.size(); ++k) {
      const std::size_t v = idx[k];
      const glm::dvec4 p(pos[3 * v], pos[3 * v + 1], pos[3 * v + 2], 1.0);
      const glm::dvec4 want = double(weights[4 * v]) * p + double(weights[4 * v + 1]) * (m1 * p);
      const glm::vec3 got = scene.triangles[k / 3].p[k % 3];
      EXPECT_NEAR(got.x, want.x, 1e-5) << "t " << t << " corner " << k;
      EXPECT_NEAR(got.y, want.y, 1e-5) << "t " << t << " corner " << k;
      EXPECT_NEAR(got.z, want.z, 1e-5) << "t " << t << " corner " << k;
    }
  }
  // The tip at t = 0.5: joint 1 turned 45 degrees about z carries vertex 5, (0.5, 2, 0), to
  // (0, 1) + R45 (0.5, 1) = ((0.5 - 1) / sqrt 2, 1 + 1.5 / sqrt 2).
  animator.pose(0.5);
  EXPECT_NEAR(scene.triangles[2].p[2].x, -0.5 / std::sqrt(2.0), 1e-5);
  EXPECT_NEAR(scene.triangles[2].p[2].y, 1.0 + 1.5 / std::sqrt(2.0), 1e-5);
  // The clip loops: at t = 1 (its length) it is back at its start, the rest pose here.
  animator.pose(1.0);
  EXPECT_NEAR(scene.triangles[2].p[2].x, 0.5f, 1e-6);
  EXPECT_NEAR(scene.triangles[2].p[2].y, 2.0f, 1e-6);
}

// ---- devices ----

// A grey floor under a red cube that slides and turns (moving_cube_file's clip, lowered
// onto the floor), lit by the default sky; 24 x 24 units of floor.
std::string cube_on_floor_file(const TempDir& dir) {
  GltfBuilder g;
  g.add("materials", {{"pbrMetallicRoughness", {{"baseColorFactor", {0.8, 0.2, 0.1, 1}}, {"metallicFactor", 0}}}});
  g.add("materials", {{"pbrMetallicRoughness", {{"baseColorFactor", {0.7, 0.7, 0.7, 1}}, {"metallicFactor", 0}}}});
  add_cube_mesh(g, 0);
  const int floor_pos = g.floats({-12, 0, -12, 12, 0, -12, 12, 0, 12, -12, 0, 12}, "VEC3", 4);
  g.add("meshes", {{"primitives", json::array({{{"attributes", {{"POSITION", floor_pos}}},
                                                {"indices", g.uint16s({0, 2, 1, 0, 3, 2}, "SCALAR", 6)},
                                                {"material", 1}}})}});
  const int times = g.floats({0.0f, 1.0f}, "SCALAR", 2);
  const int moves = g.floats({-1.5f, 0.5f, 0, 1.5f, 0.5f, 0}, "VEC3", 2);
  const float h = float(std::sqrt(0.5));
  const int turns = g.floats({0, 0, 0, 1, 0, h, 0, h}, "VEC4", 2);
  g.add("cameras", {{"type", "perspective"}, {"perspective", {{"yfov", 0.8}, {"znear", 0.1}}}});
  g.doc["scene"] = 0;
  g.doc["scenes"] = json::array({{{"nodes", {0, 1, 2}}}});
  g.doc["nodes"] = json::array({{{"mesh", 0}, {"translation", {-1.5, 0.5, 0}}},
                                {{"mesh", 1}},
                                {{"camera", 0}, {"translation", {0, 2.5, 6}}, {"rotation", {-0.199, 0, 0, 0.98}}}});
  g.doc["animations"] = json::array(
      {{{"samplers", json::array({{{"input", times}, {"output", moves}}, {{"input", times}, {"output", turns}}})},
        {"channels", json::array({{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}},
                                  {{"sampler", 1}, {"target", {{"node", 0}, {"path", "rotation"}}}}})}}});
  return dir.write("cube_on_floor.gltf", g.text()).string();
}

std::vector<float> pixels_of(const std::array<ImageRGB, 2>& eyes) {
  std::vector<float> out = eyes[0].rgb;
  out.insert(out.end(), eyes[1].rgb.begin(), eyes[1].rgb.end());
  return out;
}

bool bit_identical(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

TEST(SceneAnimator, TheUpdatedDevicesRenderWhatAFreshUploadOfThePoseRenders) {
  const TempDir dir;
  const std::string file = cube_on_floor_file(dir);
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  PathTracer::Options opt;
  opt.spp = 2;
  opt.bounces = 3;
  // Through the animator: loaded at rest, then brought to t = 0.3 and t = 0.7 on the devices.
  LoadedScene a = load_and_build(file, /*quiet=*/true);
  DeviceScene da(set, a.scene, a.bvh);
  SceneAnimator animator(a.scene, "all");
  animator.update(0.3, set, da);
  animator.update(0.7, set, da);
  PathTracer ta(set, da, a.scene);
  const auto via_update = pixels_of(ta.render_stereo(0.7f, 3, 64, 48, opt));
  // Independently: posed on the host, a tree built and uploaded from scratch.
  Scene b = load_scene(file);  // as load_and_build loads it: with the default sky
  SceneAnimator(b, "all").pose(0.7);
  BvhBuildOptions fast;
  fast.spatial_splits = false;
  DeviceScene db(set, b, build_world_bvh(b, fast));
  PathTracer tb(set, db, b);
  const auto fresh = pixels_of(tb.render_stereo(0.7f, 3, 64, 48, opt));
  EXPECT_TRUE(bit_identical(via_update, fresh));
  // And the pose does show: the rest pose renders differently.
  LoadedScene c = load_and_build(file, true);
  DeviceScene dc(set, c.scene, c.bvh);
  PathTracer tc(set, dc, c.scene);
  EXPECT_FALSE(bit_identical(via_update, pixels_of(tc.render_stereo(0.7f, 3, 64, 48, opt))));
}

// refit_bvh: a tree built for one pose, refitted to another, passes the validator (every
// triangle inside its leaf's box, every box inside its parent's, the wide nodes collapsed
// anew), and its SAH cost, the animator's cue to rebuild, grows when the triangles scatter.
TEST(BvhRefit, ARefittedTreeIsValidAndItsCostShowsItsDecay) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<SceneTriangle> tris(2000);
  for (auto& t : tris) {
    const glm::vec3 c(u(rng), u(rng), u(rng));
    for (int k = 0; k < 3; ++k) t.p[k] = c + 0.05f * glm::vec3(u(rng), u(rng), u(rng));
  }
  BvhBuildOptions binned;
  binned.spatial_splits = false;
  FlatBvh bvh = build_bvh(tris, binned);
  ensure_layout(bvh, bvh_layout_for(/*all_gpus=*/false));
  const double built = bvh.stats.sah_cost;
  // A small rigid motion: still a good tree.
  std::vector<SceneTriangle> moved = tris;
  for (auto& t : moved)
    for (auto& p : t.p) p += glm::vec3(0.3f, -0.2f, 0.1f);
  refit_bvh(bvh, moved);
  EXPECT_TRUE(bvh.nodes8.empty());  // dropped, to be collapsed anew
  ensure_layout(bvh, bvh_layout_for(/*all_gpus=*/false));
  BvhValidation check = validate_bvh(bvh, moved);
  EXPECT_TRUE(check.ok) << (check.errors.empty() ? "" : check.errors.front());
  EXPECT_NEAR(bvh.stats.sah_cost, built, 1e-3 * built);  // a translation keeps every ratio of areas
  // Every other triangle thrown 50 units away: the boxes that mix both halves span the gap.
  for (std::size_t i = 0; i < moved.size(); i += 2)
    for (auto& p : moved[i].p) p.x += 50.0f;
  refit_bvh(bvh, moved);
  ensure_layout(bvh, bvh_layout_for(/*all_gpus=*/false));
  check = validate_bvh(bvh, moved);
  EXPECT_TRUE(check.ok) << (check.errors.empty() ? "" : check.errors.front());
  EXPECT_GT(bvh.stats.sah_cost, SceneAnimator::kRebuildGrowth * built);
  // A tree of the wrong size is refused.
  moved.pop_back();
  EXPECT_THROW(refit_bvh(bvh, moved), std::invalid_argument);
}

// A room that stands still around one moving thing: `still` cubes on a grid and, last, one cube
// that slides along x, built as a rig directly (no file), lit by a white sky.
Scene still_room_with_one_mover(std::size_t still) {
  auto rig = std::make_shared<SceneRig>();
  rig->primitives.push_back(cube_primitive(0.3f));
  const std::size_t side = 50;
  for (std::size_t i = 0; i <= still; ++i) {
    RigNode node;
    node.translation =
        i < still ? glm::dvec3(double(i % side) - 25.0, -2.0, -double(i / side) - 3.0) : glm::dvec3(0.0, 0.0, -4.0);
    add_rig_node(*rig, node, 0);
  }
  AnimationClip clip;
  clip.duration = 1.0;
  AnimationChannel slide;
  slide.node = static_cast<int>(still);
  slide.track.times = {0.0, 1.0};
  slide.track.values = {glm::dvec4(0.0, 0.0, -4.0, 0.0), glm::dvec4(2.0, 0.0, -4.0, 0.0)};
  clip.channels.push_back(slide);
  rig->clips.push_back(clip);
  Scene scene = rig_scene(rig, "still room");
  scene.camera.position = glm::vec3(0.0f, 1.0f, 2.0f);
  scene.camera.target = glm::vec3(0.0f, -1.0f, -6.0f);
  return scene;
}

// Only what changed travels: with one cube of 2,001 moving, a frame writes a small part of the
// geometry (whole 16 KiB pieces around what moved), a frame that changes nothing writes
// nothing, and the devices still render what a fresh upload of the pose renders.
TEST(SceneAnimator, AFrameSendsOnlyThePiecesThatChanged) {
  Scene scene = still_room_with_one_mover(2000);
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  DeviceScene ds(set, scene, build_bvh(scene.triangles));
  SceneAnimator animator(scene, "all");
  const SceneAnimator::Update first = animator.update(0.0, set, ds);  // writes everything
  const SceneAnimator::Update moved = animator.update(0.25, set, ds);
  EXPECT_FALSE(moved.rebuilt);
  EXPECT_GT(moved.bytes, 0u);
  std::printf("one cube of 2,001 moving: the first update wrote %zu bytes, a moving frame %zu\n", first.bytes,
              moved.bytes);
  EXPECT_LT(moved.bytes, first.bytes / 4);
  const SceneAnimator::Update held = animator.update(0.25, set, ds);  // the same instant again
  EXPECT_LT(held.bytes, moved.bytes);                                 // only the motion buffer: no motion now
  const SceneAnimator::Update again = animator.update(0.25, set, ds);
  EXPECT_EQ(again.bytes, 0u);
  PathTracer::Options opt;
  opt.spp = 2;
  opt.bounces = 2;
  PathTracer ta(set, ds, scene);
  const auto via_update = pixels_of(ta.render_stereo(0.25f, 1, 48, 32, opt));
  Scene fresh = still_room_with_one_mover(2000);
  SceneAnimator(fresh, "all").pose(0.25);
  BvhBuildOptions binned;
  binned.spatial_splits = false;
  FlatBvh tree = build_bvh(fresh.triangles, binned);
  DeviceScene df(set, fresh, std::move(tree));
  PathTracer tf(set, df, fresh);
  EXPECT_TRUE(bit_identical(via_update, pixels_of(tf.render_stereo(0.25f, 1, 48, 32, opt))));
}

// Once on the devices, a static scene's host triangles are released (their count and bounds
// kept), and it still renders what it rendered; an animated scene keeps them to pose them.
TEST(SceneOnDevices, AStaticScenesHostTrianglesAreReleasedAnAnimatedOnesKept) {
  const TempDir dir;
  SceneOnDevices still("cornell", {1, DeviceMode::Auto, "", std::nullopt}, /*quiet=*/true);
  EXPECT_TRUE(still.loaded.scene.triangles.empty());
  EXPECT_GT(still.loaded.triangle_count, 10u);
  EXPECT_LT(still.loaded.bounds_lo.x, still.loaded.bounds_hi.x);
  EXPECT_GT(still.loaded.times.host_rss_after_start_mib, 0.0);
  PathTracer::Options opt;
  opt.spp = 1;
  const auto released =
      pixels_of(PathTracer(still.devices, still.device_scene, still.loaded.scene).render_stereo(0.0f, 0, 16, 12, opt));
  const LoadedScene kept = load_and_build("cornell", true);
  DeviceScene ds(still.devices, kept.scene, kept.bvh);
  EXPECT_TRUE(bit_identical(released,
                            pixels_of(PathTracer(still.devices, ds, kept.scene).render_stereo(0.0f, 0, 16, 12, opt))));
  SceneOnDevices moving(cube_on_floor_file(dir), {1, DeviceMode::Auto, "", std::nullopt}, true);
  EXPECT_EQ(moving.loaded.scene.triangles.size(), moving.loaded.triangle_count);
}

// Every frame of an animation, denoised, with 1 and 3 devices.
std::vector<std::vector<float>> animated_frames(const std::string& file, int devices, unsigned frames,
                                                const SceneLoadOptions& options = {}) {
  LoadedScene loaded = load_and_build(file, true, options);
  DeviceSet set = DeviceSet::create({devices, DeviceMode::Auto, "", std::nullopt});
  DeviceScene ds(set, loaded.scene, loaded.bvh);
  SceneAnimator animator(loaded.scene, "all");
  StereoPipeline::Options opt;
  opt.trace.spp = 1;
  opt.trace.bounces = 3;
  StereoPipeline p(set, ds, loaded.scene, 64, 40, opt);
  std::vector<std::vector<float>> out;
  for (unsigned f = 0; f < frames; ++f) {
    const double t = f / 8.0;
    animator.update(t, set, ds);
    p.render(f, static_cast<float>(t));
    out.push_back(pixels_of(p.radiance()));
  }
  return out;
}

TEST(SceneAnimator, NDevicesAreBitIdenticalWithAnimationPlaying) {
  const TempDir dir;
  const std::string file = cube_on_floor_file(dir);
  const auto one = animated_frames(file, 1, 4), three = animated_frames(file, 3, 4);
  for (std::size_t f = 0; f < one.size(); ++f) EXPECT_TRUE(bit_identical(one[f], three[f])) << "frame " << f;
  EXPECT_FALSE(bit_identical(one[0], one[3]));  // the cube moved
}

// The sliding cube is a rigid mesh on a moving node: drawn as an instance, its matrix moves it
// and its triangles are neither posed nor refitted; loaded without instancing it is posed into
// the world's triangles as before. Both render the same denoised frames (SVGF's history and the
// anti-aliasing follow the cube through the instance's matrices or through its vertices) but
// for rounding (the cube's vertices placed on the device or on the host).
TEST(SceneAnimator, AMovingInstanceRendersTheFramesOfItsPosedCopy) {
  const TempDir dir;
  const std::string file = cube_on_floor_file(dir);
  {
    const Scene s = load_gltf(file);
    ASSERT_EQ(s.instancing.instances.size(), 1u) << "the moving cube is an instance";
    EXPECT_EQ(s.instancing.world_triangles, 2u) << "the floor is the world's";
  }
  const auto instanced = animated_frames(file, 2, 4);
  SceneLoadOptions flat;
  flat.instancing = false;
  EXPECT_TRUE(load_gltf(file, flat).instancing.empty());
  const auto posed = animated_frames(file, 2, 4, flat);
  ASSERT_EQ(instanced.size(), posed.size());
  for (std::size_t f = 0; f < posed.size(); ++f) {
    double se = 0.0, peak = 0.0;
    for (std::size_t i = 0; i < posed[f].size(); ++i) {
      se += (double(instanced[f][i]) - posed[f][i]) * (double(instanced[f][i]) - posed[f][i]);
      peak = std::max(peak, double(posed[f][i]));
    }
    const double mse = se / double(posed[f].size());
    const double psnr = mse > 0.0 ? 10.0 * std::log10(peak * peak / mse) : 200.0;
    EXPECT_GT(psnr, 45.0) << "frame " << f;
    std::printf("frame %zu: PSNR %.1f dB against the posed copy\n", f, psnr);
  }
  EXPECT_FALSE(bit_identical(instanced[0], instanced[3]));  // the cube moved
}

// The motion pass (kernels/pipeline/motion.cl) on a quad that turned by 20 degrees about y and
// moved by (0.3, -0.2, 0.5) since the last frame: every point's previous position is the
// inverse motion of where it is now.
TEST(MotionPass, AMovingQuadsPointsGoBackAlongItsAnalyticMotion) {
  DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  const glm::dvec3 move(0.3, -0.2, 0.5);
  const glm::dmat4 motion = glm::rotate(glm::translate(glm::dmat4(1.0), move), 20.0 * kPi / 180.0, glm::dvec3(0, 1, 0));
  const glm::dmat4 back = glm::inverse(motion);
  const glm::dvec3 before[4] = {{-1, 0, -1}, {1, 0.2, -1}, {1, 0.1, 1}, {-1, -0.1, 1}};
  glm::dvec3 now[4];
  for (int i = 0; i < 4; ++i) now[i] = glm::dvec3(motion * glm::dvec4(before[i], 1.0));
  const int tris[2][3] = {{0, 1, 2}, {0, 2, 3}};
  std::vector<cl_float4> tri_motion;
  for (const auto& t : tris) {
    for (int c = 0; c < 3; ++c) tri_motion.push_back({{float(now[t[c]].x), float(now[t[c]].y), float(now[t[c]].z), 0}});
    for (int c = 0; c < 3; ++c)
      tri_motion.push_back({{float(before[t[c]].x), float(before[t[c]].y), float(before[t[c]].z), 0}});
  }
  // 64 texels: points at random barycentrics of either triangle, and one miss.
  const unsigned width = 8, rows = 8;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::vector<GBufferTexel> gbuf(width * rows);
  std::vector<glm::dvec3> want(gbuf.size());
  for (std::size_t i = 0; i < gbuf.size(); ++i) {
    GBufferTexel& g = gbuf[i];
    std::memset(&g, 0, sizeof g);
    const int t = static_cast<int>(i % 2);
    double b1 = u01(rng), b2 = u01(rng);
    if (b1 + b2 > 1.0) b1 = 1.0 - b1, b2 = 1.0 - b2;
    const glm::dvec3 p =
        now[tris[t][0]] + b1 * (now[tris[t][1]] - now[tris[t][0]]) + b2 * (now[tris[t][2]] - now[tris[t][0]]);
    g.pos[0] = float(p.x), g.pos[1] = float(p.y), g.pos[2] = float(p.z);
    g.material_class = PX_CLASS_DIFFUSE;
    g.prim = static_cast<std::uint32_t>(t);
    g.inst = PX_NO_INSTANCE;
    want[i] = glm::dvec3(back * glm::dvec4(glm::dvec3(g.pos[0], g.pos[1], g.pos[2]), 1.0));
    // Every third texel lies on the quad as the mesh of an instance instead (placed by `motion`
    // now, by the identity before): the instance's matrices move it, not the triangle's vertices.
    if (i % 3 == 2) g.inst = 0;
  }
  gbuf[5].material_class = PX_CLASS_MISS;
  gbuf[5].prim = PX_NO_HIT;
  gbuf[5].inst = PX_NO_INSTANCE;
  Scene inst_scene;
  inst_scene.materials.resize(1);
  for (const auto& t : tris)
    append_triangle(inst_scene.triangles, glm::vec3(before[t[0]]), glm::vec3(before[t[1]]), glm::vec3(before[t[2]]), 0);
  inst_scene.instancing.meshes.push_back({0, inst_scene.triangles.size()});
  inst_scene.instancing.instances.push_back({0, glm::mat4(motion)});
  const std::vector<glm::mat4> previous{glm::mat4(1.0f)};
  const std::vector<std::uint32_t> inst_words =
      instance_buffer_words(inst_scene, {MeshPlacement{}}, 0, nullptr, &previous);
  const cl::Context& ctx = set.context();
  cl::CommandQueue& q = set.devices()[0].queue;
  cl::Buffer g_buf(ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, gbuf.size() * sizeof(GBufferTexel), gbuf.data());
  cl::Buffer m_buf(ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, tri_motion.size() * sizeof(cl_float4),
                   tri_motion.data());
  cl::Buffer i_buf(ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, inst_words.size() * 4,
                   const_cast<std::uint32_t*>(inst_words.data()));
  cl::Buffer out(ctx, CL_MEM_WRITE_ONLY, gbuf.size() * sizeof(cl_float4));
  cl::Kernel k(set.program("pipeline/motion.cl"), "gbuffer_motion");
  k.setArg(0, out);
  k.setArg(1, g_buf);
  k.setArg(2, m_buf);
  k.setArg(3, i_buf);
  k.setArg(4, cl_uint(0));
  k.setArg(5, cl_uint(rows));
  k.setArg(6, cl_uint(width));
  launch_1d(q, k, gbuf.size());
  std::vector<cl_float4> got(gbuf.size());
  q.enqueueReadBuffer(out, CL_TRUE, 0, got.size() * sizeof(cl_float4), got.data());
  for (std::size_t i = 0; i < gbuf.size(); ++i) {
    if (i == 5) {  // a miss keeps its direction, marked w = 0
      EXPECT_EQ(got[i].s[3], 0.0f);
      EXPECT_EQ(got[i].s[0], gbuf[i].pos[0]);
      continue;
    }
    EXPECT_EQ(got[i].s[3], PX_MOTION_MOVED);  // the quad moved, as an instance and as triangles
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[i].s[c], want[i][c], 2e-5) << "texel " << i << " axis " << c;
  }
}

// The motion edges (kernels/pipeline/motion_edges.cl) of the sliding cube mid-clip, against
// the rule evaluated on the host from the same G-buffer: a texel on the cube (its instance is
// the only thing that moves) with a floor texel among its 3x3 neighbours and no sky, or a floor
// texel with the cube within its 5x5 neighbourhood. Then the extra samples
// (path_trace_list_more): a listed pixel becomes what a render with that many more samples
// gives it (its first sample is the frame's, the rest continue its stream), up to rounding; no
// other pixel changes.
TEST(MotionEdges, TheListedPixelsAreTheCubesEdgesAndTheirSamplesJoinTheirOwnStream) {
  const TempDir dir;
  const std::string file = cube_on_floor_file(dir);
  const unsigned w = 96, h = 64;
  DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  LoadedScene loaded = load_and_build(file, true);
  ASSERT_FALSE(loaded.scene.instancing.empty());
  DeviceScene ds(set, loaded.scene, loaded.bvh);
  SceneAnimator animator(loaded.scene, "all");
  StereoPipeline::Options opt;
  opt.trace.spp = 1;
  StereoPipeline p(set, ds, loaded.scene, w, h, opt);
  for (unsigned f = 0; f < 3; ++f) {
    animator.update(0.3 + f / 30.0, set, ds);
    p.render(f, static_cast<float>(0.3 + f / 30.0));
  }
  const std::vector<GBufferTexel> g = p.gbuffer_of(0);
  // The host's rule.
  auto at = [&](int x, int y) -> const GBufferTexel& { return g[static_cast<std::size_t>(y) * w + x]; };
  auto cube = [&](const GBufferTexel& t) { return t.material_class != PX_CLASS_MISS && t.inst != PX_NO_INSTANCE; };
  std::vector<std::uint32_t> want;
  for (int y = 0; y < int(h); ++y)
    for (int x = 0; x < int(w); ++x) {
      const GBufferTexel& t = at(x, y);
      if (t.material_class == PX_CLASS_MISS) continue;
      const int reach = cube(t) ? 1 : 2;
      bool other = false, sky = false;
      for (int dy = -reach; dy <= reach; ++dy)
        for (int dx = -reach; dx <= reach; ++dx) {
          if ((dx == 0 && dy == 0) || x + dx < 0 || x + dx >= int(w) || y + dy < 0 || y + dy >= int(h)) continue;
          const GBufferTexel& q = at(x + dx, y + dy);
          sky |= q.material_class == PX_CLASS_MISS;
          other |= cube(q) != cube(t);
        }
      if (other && !(cube(t) && sky)) want.push_back(static_cast<std::uint32_t>(y) * w + x);
    }
  ASSERT_GT(want.size(), 40u) << "the cube's outline";
  // The kernel's list.
  const cl::Context& ctx = set.context();
  cl::CommandQueue& q = set.devices()[0].queue;
  const DeviceSceneBuffers& sb = ds.on(0);
  cl::Buffer gbuf(ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, g.size() * sizeof(GBufferTexel),
                  const_cast<GBufferTexel*>(g.data()));
  cl::Buffer list(ctx, CL_MEM_READ_WRITE, g.size() * sizeof(cl_uint));
  const cl_uint zero = 0;
  cl::Buffer count(ctx, CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR, sizeof zero, const_cast<cl_uint*>(&zero));
  cl::Kernel k(set.program("pipeline/motion_edges.cl"), "motion_edge_list");
  k.setArg(0, list);
  k.setArg(1, count);
  k.setArg(2, gbuf);
  k.setArg(3, sb.motion);
  k.setArg(4, sb.instances);
  k.setArg(5, cl_uint(0));
  k.setArg(6, cl_uint(h));
  k.setArg(7, cl_uint(w));
  k.setArg(8, cl_uint(h));
  k.setArg(9, cl_uint(0));
  k.setArg(10, cl_uint(h));
  launch_1d(q, k, g.size());
  cl_uint n = 0;
  q.enqueueReadBuffer(count, CL_TRUE, 0, sizeof n, &n);
  std::vector<std::uint32_t> got(n);
  if (n) q.enqueueReadBuffer(list, CL_TRUE, 0, n * sizeof(cl_uint), got.data());
  std::sort(got.begin(), got.end());
  EXPECT_EQ(got, want);
  // The pipeline listed as many in the last frame (the G-buffer is that frame's).
  EXPECT_EQ(p.motion_edge_pixels(0), want.size());

  // Extra samples: the frame's 1 spp, 8 more for the listed pixels, against 9 spp.
  const float t = static_cast<float>(0.3 + 2 / 30.0);
  const CameraParams cam = make_eye_camera(evaluate_camera(loaded.scene, t), Eye::Left, loaded.scene.ipd_units(), w, h);
  const cl::Program& program = set.program("pathtrace/path_trace.cl", ds.kernel_options());
  auto trace = [&](unsigned spp) {
    cl::Buffer radiance(ctx, CL_MEM_READ_WRITE, g.size() * sizeof(cl_float4));
    cl::Buffer albedo(ctx, CL_MEM_READ_WRITE, g.size() * sizeof(cl_float4));
    cl::Buffer nonfinite(ctx, CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR, sizeof zero, const_cast<cl_uint*>(&zero));
    PathTracer::Options o;
    o.spp = spp;
    PathTracer::launch(q, program, sb, {radiance, albedo, nonfinite},
                       PathTracer::frame_params(loaded.scene, ds.light_count(), o, 0, 0, h, 2), cam, w);
    return std::array<cl::Buffer, 3>{radiance, albedo, nonfinite};
  };
  auto read = [&](const cl::Buffer& b) {
    std::vector<cl_float4> v(g.size());
    q.enqueueReadBuffer(b, CL_TRUE, 0, v.size() * sizeof(cl_float4), v.data());
    return v;
  };
  const auto one = trace(1), nine = trace(9);
  const std::vector<cl_float4> before = read(one[0]), want9 = read(nine[0]), want9_albedo = read(nine[1]);
  PathTracer::Options o;
  o.spp = 1;
  FrameParams fp = PathTracer::frame_params(loaded.scene, ds.light_count(), o, 0, 0, h, 2);
  fp.sample_offset = 1;
  fp.spp = 8;
  cl::Kernel more(program, "path_trace_list_more");
  more.setArg(0, one[0]);
  more.setArg(1, one[1]);
  more.setArg(2, one[2]);
  more.setArg(3, list);
  more.setArg(4, count);
  more.setArg(5, fp);
  more.setArg(6, cam);
  sb.bind(more, 7);
  launch_1d(q, more, g.size());
  const std::vector<cl_float4> after = read(one[0]), after_albedo = read(one[1]);
  std::vector<char> listed(g.size(), 0);
  for (std::uint32_t i : want) listed[i] = 1;
  for (std::size_t i = 0; i < g.size(); ++i) {
    if (!listed[i]) {
      EXPECT_EQ(std::memcmp(&after[i], &before[i], sizeof(cl_float4)), 0) << "pixel " << i << " not listed";
      continue;
    }
    EXPECT_EQ(after[i].s[3], want9[i].s[3]) << "pixel " << i << ": finite samples";
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(after[i].s[c], want9[i].s[c], 1e-5f * (1.0f + want9[i].s[c])) << "pixel " << i;
      EXPECT_NEAR(after_albedo[i].s[c], want9_albedo[i].s[c], 1e-5f) << "pixel " << i << " albedo";
    }
  }
}

// Trail: the cube slides and turns over the floor (3 units and 90 degrees a second, 30 fps),
// denoised; against a 256-spp reference of the last frame's time, the error in the region the
// cube swept over the last eight frames (its G-buffer coverage in any of them, the last one
// included) is compared with the error of the same region in a run whose cube stood still at
// that last pose from the start. A trail (the cube's history left on the floor, a lagging edge)
// is error the still run does not have. At 1 spp (the issue's case) most of either run's error
// is noise; at 8 spp what stays is lag, which more samples do not take away.
// The ratios measured now and before each fix: docs/measurements.md, motion trail.
// What remains: a pixel the cube uncovered has only the frames since; the floor's history
// still lags the moving contact shadow a little; on the cube, a moving pixel keeps at most half
// of the anti-aliasing's history (PX_TAA_MOTION_ALPHA_MAX, as each bilinear read blurs it), a
// still one nearly all. The goal is a ratio of 1.5; the bounds here guard what is reached.
TEST(MotionTrail, AMovingObjectLeavesNoMoreErrorWhereItWentThanAStillOne) {
  const TempDir dir;
  const std::string file = cube_on_floor_file(dir);
  const unsigned w = 96, h = 64, frames = 24;
  const double fps = 30.0, t_end = (frames - 1) / fps;
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  // The region: pixels whose G-buffer saw the cube: its instance (a rigid mesh on a moving
  // node), or loaded without instancing one of its 12 posed triangles (the first mesh).
  std::size_t edge_pixels = 0;  // the moving run's pixels with extra samples, over its frames
  auto run = [&](bool moving, unsigned spp, std::vector<char>* swept) {
    LoadedScene loaded = load_and_build(file, true);
    const bool instanced = !loaded.scene.instancing.empty();
    DeviceScene ds(set, loaded.scene, loaded.bvh);
    SceneAnimator animator(loaded.scene, "all");
    StereoPipeline::Options opt;
    opt.trace.spp = spp;
    opt.trace.bounces = 3;
    StereoPipeline p(set, ds, loaded.scene, w, h, opt);
    for (unsigned f = 0; f < frames; ++f) {
      const double t = moving ? f / fps : t_end;
      animator.update(t, set, ds);
      p.render(f, static_cast<float>(t));
      if (swept) edge_pixels += p.motion_edge_pixels(0) + p.motion_edge_pixels(1);
      if (swept && f + 8 >= frames)
        for (int e = 0; e < 2; ++e) {
          const std::vector<GBufferTexel> g = p.gbuffer_of(e);
          for (std::size_t i = 0; i < g.size(); ++i)
            if (instanced ? g[i].inst != PX_NO_INSTANCE : g[i].prim < 12)
              (*swept)[e * g.size() + i] = f + 1 == frames ? 2 : std::max<char>((*swept)[e * g.size() + i], 1);
        }
    }
    return pixels_of(p.radiance());
  };
  // The reference at the last frame's time.
  std::vector<float> ref;
  {
    LoadedScene loaded = load_and_build(file, true);
    DeviceScene ds(set, loaded.scene, loaded.bvh);
    SceneAnimator animator(loaded.scene, "all");
    animator.update(t_end, set, ds);
    PathTracer tracer(set, ds, loaded.scene);
    PathTracer::Options ro;
    ro.spp = 256;
    ro.bounces = 3;
    ro.first_sample_on_gbuffer_ray = false;
    ref = pixels_of(tracer.render_stereo(static_cast<float>(t_end), 0, w, h, ro));
  }
  for (const auto& [spp, bound] : {std::pair{1u, 1.5}, std::pair{8u, 2.8}}) {
    std::vector<char> swept(2 * w * h, 0);
    edge_pixels = 0;
    const std::vector<float> moving = run(true, spp, &swept), still = run(false, spp, nullptr);
    // The extra samples at the moving cube's edges (the still run has none): their share of the
    // moving run's paths.
    const double extra = double(edge_pixels) * DenoiseStage::Options{}.motion_edge_samples;
    EXPECT_GT(edge_pixels, 0u);
    std::printf("%u spp: %.1f pixels a frame and eye got %u samples more: %.1f%% more paths\n", spp,
                double(edge_pixels) / (2.0 * frames), DenoiseStage::Options{}.motion_edge_samples,
                100.0 * extra / (2.0 * frames * w * h * spp));
    // The swept region is where the cube was: its last pose in the G-buffer matches the
    // reference's (a G-buffer a frame old would put it 1.2 pixels behind).
    std::size_t last = 0, dark = 0;
    for (std::size_t i = 0; i < swept.size(); ++i)
      if (swept[i] == 2) {
        ++last;
        dark += ref[3 * i + 1] < 0.3f;  // the red cube reflects little green; the grey floor a lot
      }
    EXPECT_GT(dark, last * 9 / 10) << spp << " spp: the last frame's cube pixels are the reference's cube";
    double err_moving = 0.0, err_still = 0.0, err_rest = 0.0;
    double on_moving = 0.0, on_still = 0.0;  // the part of the region the cube covers at the end
    std::size_t n = 0, rest = 0, on = 0;
    for (std::size_t i = 0; i < swept.size(); ++i) {
      double em = 0.0, es = 0.0;
      for (int c = 0; c < 3; ++c) {
        em += std::pow(moving[3 * i + c] - ref[3 * i + c], 2.0);
        es += std::pow(still[3 * i + c] - ref[3 * i + c], 2.0);
      }
      if (swept[i]) {
        err_moving += em;
        err_still += es;
        ++n;
        if (swept[i] == 2) {
          on_moving += em;
          on_still += es;
          ++on;
        }
      } else {
        err_rest += em;
        ++rest;
      }
    }
    ASSERT_GT(n, 200u);
    std::printf("%u spp: the last frame's cube: %zu pixels, %zu dark in the reference\n", spp, last, dark);
    std::printf("%u spp: swept region: %zu pixels, mse moving %.4g, still %.4g (x%.2f); elsewhere (moving run) %.4g\n",
                spp, n, err_moving / n, err_still / n, err_moving / err_still, err_rest / rest);
    // Where the error is: on the cube as it stands at the end, or on the floor it left.
    std::printf("  of which the cube at the end: %zu pixels, x%.2f; the floor it left: %zu pixels, x%.2f\n", on,
                on_still > 0.0 ? on_moving / on_still : 0.0, n - on,
                err_still - on_still > 0.0 ? (err_moving - on_moving) / (err_still - on_still) : 0.0);
    EXPECT_LE(err_moving / n, bound * err_still / n) << spp << " spp";
  }
}

// ---- lights that move ----

// A directional light (KHR_lights_punctual, 3 lux) on a node that turns about x over two
// seconds (LINEAR: keys at 0, 1, 2 s), as the child of `parent` node 0 which the clip turns,
// with a fixed turn of its own (`child_rotation`, x y z w); a grey floor at y = 0 (24 x 24), a
// camera 3 units above it looking straight down. `keys` holds the parent's rotations.
std::string turning_sun_file(const TempDir& dir, const std::vector<glm::dquat>& keys,
                             const glm::dquat& child_rotation) {
  GltfBuilder g;
  const int floor_pos = g.floats({-12, 0, -12, 12, 0, -12, 12, 0, 12, -12, 0, 12}, "VEC3", 4);
  g.add("meshes", {{"primitives", json::array({{{"attributes", {{"POSITION", floor_pos}}},
                                                {"indices", g.uint16s({0, 2, 1, 0, 3, 2}, "SCALAR", 6)}}})}});
  std::vector<float> times, quats;
  for (std::size_t k = 0; k < keys.size(); ++k) {
    times.push_back(float(k));
    for (double v : {keys[k].x, keys[k].y, keys[k].z, keys[k].w}) quats.push_back(float(v));
  }
  const int in = g.floats(times, "SCALAR", keys.size()), out = g.floats(quats, "VEC4", keys.size());
  g.add("cameras", {{"type", "perspective"}, {"perspective", {{"yfov", 0.8}, {"znear", 0.1}}}});
  const double h = std::sqrt(0.5);
  g.doc["extensionsUsed"] = {"KHR_lights_punctual"};
  g.doc["extensions"] = {
      {"KHR_lights_punctual", {{"lights", json::array({{{"type", "directional"}, {"intensity", 3.0}}})}}}};
  g.doc["scene"] = 0;
  g.doc["scenes"] = json::array({{{"nodes", {0, 2, 3}}}});
  g.doc["nodes"] = json::array({{{"children", {1}}},
                                {{"rotation", {child_rotation.x, child_rotation.y, child_rotation.z, child_rotation.w}},
                                 {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}},
                                {{"mesh", 0}},
                                {{"camera", 0}, {"translation", {0, 3, 0}}, {"rotation", {-h, 0, 0, h}}}});
  g.doc["animations"] =
      json::array({{{"name", "day"},
                    {"samplers", json::array({{{"input", in}, {"output", out}}})},
                    {"channels", json::array({{{"sampler", 0}, {"target", {{"node", 0}, {"path", "rotation"}}}}})}}});
  return dir.write("turning_sun.gltf", g.text()).string();
}

glm::dquat about_x(double degrees) { return glm::angleAxis(glm::radians(degrees), glm::dvec3(1, 0, 0)); }

// The sun follows its node through an animated ancestor: at every time its direction is the
// light's +z (it shines along -z) turned by the parent's keyed rotation (slerped between keys,
// written here with glm) and the child's own turn. Only the sun moves: no geometry changes.
TEST(MovingLights, AnAnimatedDirectionalLightTurnsTheSun) {
  const TempDir dir;
  const std::vector<glm::dquat> keys = {about_x(-90), about_x(-60), about_x(-20)};
  const glm::dquat child = glm::angleAxis(glm::radians(30.0), glm::dvec3(0, 1, 0));
  Scene scene = load_scene(turning_sun_file(dir, keys, child));
  ASSERT_TRUE(scene.sun.enabled);
  const Sun loaded = scene.sun;
  const std::vector<SceneTriangle> rest = scene.triangles;
  SceneAnimator animator(scene, "all");
  EXPECT_TRUE(animator.moves());
  EXPECT_TRUE(animator.sun_moves());
  EXPECT_NE(animator.describe().find("turning the sun"), std::string::npos) << animator.describe();
  for (double t : {0.0, 0.25, 1.0, 1.6, 2.0, 2.5}) {
    animator.pose(t);
    const double ct = std::fmod(t, 2.0);  // the clip loops over its 2 s
    const std::size_t k = std::min<std::size_t>(std::size_t(ct), 1);
    const glm::dquat parent = glm::slerp(keys[k], keys[k + 1], ct - double(k));
    const glm::dvec3 towards = parent * child * glm::dvec3(0, 0, 1);
    EXPECT_NEAR(scene.sun.direction.x, towards.x, 1e-5) << t;
    EXPECT_NEAR(scene.sun.direction.y, towards.y, 1e-5) << t;
    EXPECT_NEAR(scene.sun.direction.z, towards.z, 1e-5) << t;
    // Well above the horizon all along (at least 20 degrees): the radiance is the light's.
    EXPECT_EQ(scene.sun.radiance, loaded.radiance) << t;
    EXPECT_EQ(scene.triangles.size(), rest.size());
    EXPECT_TRUE(std::memcmp(scene.triangles.data(), rest.data(), rest.size() * sizeof(SceneTriangle)) == 0);
  }
  // --animation none: the sun stays at rest.
  Scene still = load_scene(turning_sun_file(dir, keys, child));
  SceneAnimator none(still, "none");
  EXPECT_FALSE(none.moves());
  none.pose(1.0);
  EXPECT_EQ(still.sun.direction, loaded.direction);
  // A scene file that gives the sun its own direction keeps it.
  const std::string placed = dir.write("placed.json", R"({"mesh": "turning_sun.gltf",
      "sun": {"direction": [0, 1, 0], "radiance": [5, 5, 5]}})")
                                 .string();
  Scene fixed = load_scene(placed);
  SceneAnimator(fixed, "all").pose(1.0);
  EXPECT_EQ(fixed.sun.direction, glm::vec3(0, 1, 0));
}

// A scene file's sun keys, against interpolation worked by hand: the direction turns along
// the great circle at an even angular speed between keys, holds outside them, and the sun
// fades as its disk sets (0.27 degrees radius: half of it at elevation 0, none below).
TEST(MovingLights, SunKeysInterpolateAlongTheGreatCircleAndSet) {
  const TempDir dir;
  dir.write("tri.obj", "v -1 0 -1\nv 1 0 -1\nv 0 0 1\nf 1 3 2\n");
  const std::string file = dir.write("day.json", R"({"mesh": "tri.obj", "sun": {"radiance": [100, 90, 80],
      "keys": [{"time": 0, "direction": [0, 1, 0]}, {"time": 2, "direction": [2, 2, 0]},
               {"time": 3, "direction": [1, 0, 0]}, {"time": 4, "direction": [1, -1, 0]}]}})")
                               .string();
  Scene scene = load_scene(file);
  ASSERT_EQ(scene.sun_path.size(), 4u);
  EXPECT_EQ(scene.sun.direction, glm::vec3(0, 1, 0));  // the first key's until posed
  SceneAnimator animator(scene, "none");               // keys play whatever --animation says
  ASSERT_TRUE(animator.moves());
  const double s22 = std::sin(kPi / 8), c22 = std::cos(kPi / 8), r = std::sqrt(0.5);
  struct Expect {
    double t, x, y, fade;
  };
  const Expect cases[] = {
      {0.0, 0, 1, 1},      {1.0, s22, c22, 1},                   // half of 45 degrees from the zenith
      {2.0, r, r, 1},      {2.5, c22, s22, 1},                   // 67.5 degrees from the zenith
      {3.0, 1, 0, 0.5},                                          // on the horizon: half the disk
      {3.5, c22, -s22, 0}, {4.0, r, -r, 0},    {9.0, r, -r, 0},  // set, and held
  };
  for (const Expect& e : cases) {
    animator.pose(e.t);
    EXPECT_NEAR(scene.sun.direction.x, e.x, 1e-6) << e.t;
    EXPECT_NEAR(scene.sun.direction.y, e.y, 1e-6) << e.t;
    EXPECT_NEAR(scene.sun.direction.z, 0.0, 1e-6) << e.t;
    EXPECT_NEAR(scene.sun.radiance.x, 100.0 * e.fade, 1e-3) << e.t;
    EXPECT_NEAR(scene.sun.radiance.z, 80.0 * e.fade, 1e-3) << e.t;
    EXPECT_TRUE(scene.sun.enabled);  // the kernels keep their sun feature; a set sun gives nothing
  }
  EXPECT_NEAR(sun_above_horizon(glm::vec3(1, 0.5f * std::sin(glm::radians(0.27f)), 0), 0.27f), 0.75f, 1e-3);
}

// The mean radiance of a render's pixels (both eyes).
double mean_of(const std::array<ImageRGB, 2>& eyes) {
  double sum = 0.0;
  std::size_t n = 0;
  for (const ImageRGB& e : eyes)
    for (float v : e.rgb) {
      sum += v;
      ++n;
    }
  return sum / double(n);
}

// An image check: a floor lit only by the turning glTF sun (no sky, no emitter) is as bright as
// the cosine of the sun's zenith angle says (Lambert), at the frame times `render` uses; and
// `reference --frame N` (posed once at frame N's time) and `render` (posed frame after frame
// up to N) give the kernels the same sun, to the bit.
TEST(MovingLights, AFloorLitByTheTurningSunFollowsTheCosineOfItsZenithAngle) {
  const TempDir dir;
  // Zenith at 0 s, 60 degrees from it at 1 s, 80 degrees at 2 s (the clip's end: it loops).
  const std::string gltf = turning_sun_file(dir, {about_x(-90), about_x(-30), about_x(-10)}, glm::dquat(1, 0, 0, 0));
  const std::string file = dir.write("lit.json", R"({"mesh": "turning_sun.gltf", "sky": {"enabled": false}})").string();
  DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  LoadedScene a = load_and_build(file, /*quiet=*/true);
  ASSERT_FALSE(a.scene.sky.enabled);
  DeviceScene da(set, a.scene, a.bvh);
  SceneAnimator animator(a.scene, "all");
  ASSERT_TRUE(animator.sun_moves());
  PathTracer tracer(set, da, a.scene);
  PathTracer::Options opt;
  opt.spp = 4;
  opt.bounces = 2;
  const FrameClock clock{4.0f};  // frames 0, 4, 6 at 0, 1, 1.5 s: 70 degrees from the zenith
  std::vector<double> means, cosines;
  FrameParams at_frame_6{};
  for (unsigned f = 0; f <= 6; ++f) {
    const SceneAnimator::Update u = animator.update(clock.time_s(f), set, da);
    EXPECT_EQ(u.bytes, 0u) << "only the sun moves: no geometry is written";
    if (f != 0 && f != 4 && f != 6) continue;
    means.push_back(mean_of(tracer.render_stereo(clock.camera_time_s(f), f, 32, 24, opt)));
    cosines.push_back(a.scene.sun.direction.y);
    if (f == 6) at_frame_6 = PathTracer::frame_params(a.scene, da.light_count(), opt, 0, 0, 24, f);
  }
  EXPECT_NEAR(cosines[1], 0.5, 1e-5);
  EXPECT_NEAR(cosines[2], std::cos(glm::radians(70.0)), 1e-5);
  for (std::size_t i = 1; i < means.size(); ++i) {
    const double ratio = means[i] / means[0], expected = cosines[i] / cosines[0];
    std::printf("sun %zu: floor %.4f, ratio to the zenith sun's %.4f (cosines %.4f)\n", i, means[i], ratio, expected);
    EXPECT_NEAR(ratio, expected, 0.03 * expected) << "sun " << i;
  }
  // `reference --frame 6`: a fresh load, posed once at frame 6's time.
  LoadedScene b = load_and_build(file, true);
  DeviceScene db(set, b.scene, b.bvh);
  SceneAnimator once(b.scene, "all");
  once.update(clock.time_s(6), set, db);
  const FrameParams ref = PathTracer::frame_params(b.scene, db.light_count(), opt, 0, 0, 24, 6);
  EXPECT_EQ(std::memcmp(ref.sun_dir, at_frame_6.sun_dir, sizeof ref.sun_dir), 0);
  EXPECT_EQ(std::memcmp(ref.sun_radiance, at_frame_6.sun_radiance, sizeof ref.sun_radiance), 0);
  EXPECT_EQ(ref.p_sun, at_frame_6.p_sun);
  // And the image at rest (the sun at the zenith) is not frame 6's: the check can fail.
  EXPECT_LT(means[2], 0.5 * means[0]);
}

}  // namespace
}  // namespace px
