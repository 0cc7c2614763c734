// Temporal gradients (pipeline/stages/temporal_gradients.h, kernels/denoise/temporal_gradient.cl,
// gradient_filter.cl): a light that moves is followed; nothing changes where nothing changed; the
// filter is the host's; N devices give one device's images.
#include "app/scene_setup.h"
#include "image/image_metrics.h"
#include "pipeline/stereo_pipeline.h"
#include "render/device_scene.h"
#include "render/path_tracer.h"
#include "render/scene_animator.h"
#include "support/gltf_builder.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>

namespace px {
namespace {

using nlohmann::json;
using test::GltfBuilder;
using test::TempDir;

// A still room (floor, back wall, a box) lit only by a 1 x 1 emissive panel facing down that
// slides along x from -4 to 4 over two seconds, 3.5 units up, above the camera's view: what the
// camera sees changes only through the light. The camera looks down at the box.
std::string panel_room_file(const TempDir& dir) {
  GltfBuilder g;
  g.add("materials", {{"pbrMetallicRoughness", {{"baseColorFactor", {0.7, 0.7, 0.7, 1}}, {"metallicFactor", 0}}}});
  g.add("materials", {{"pbrMetallicRoughness", {{"baseColorFactor", {0.8, 0.3, 0.2, 1}}, {"metallicFactor", 0}}}});
  g.add("materials", {{"pbrMetallicRoughness", {{"baseColorFactor", {0, 0, 0, 1}}, {"metallicFactor", 0}}},
                      {"emissiveFactor", {1, 1, 1}},
                      {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 20}}}}}});
  g.doc["extensionsUsed"] = {"KHR_materials_emissive_strength"};
  auto quad = [&](std::vector<float> p, int material) {
    g.add("meshes", {{"primitives", json::array({{{"attributes", {{"POSITION", g.floats(p, "VEC3", 4)}}},
                                                  {"indices", g.uint16s({0, 1, 2, 0, 2, 3}, "SCALAR", 6)},
                                                  {"material", material}}})}});
  };
  quad({-4, 0, 9, 4, 0, 9, 4, 0, -4, -4, 0, -4}, 0);                          // mesh 0: floor, facing up
  quad({-4, 0, -4, 4, 0, -4, 4, 4, -4, -4, 4, -4}, 0);                        // mesh 1: back wall, facing +z
  quad({-0.5f, 0, -0.5f, 0.5f, 0, -0.5f, 0.5f, 0, 0.5f, -0.5f, 0, 0.5f}, 2);  // mesh 2: panel, facing down
  // mesh 3: a unit box, 12 triangles
  std::vector<float> p;
  for (int i = 0; i < 8; ++i) {
    p.push_back((i & 1) ? 0.5f : -0.5f);
    p.push_back((i & 2) ? 1.0f : 0.0f);
    p.push_back((i & 4) ? 0.5f : -0.5f);
  }
  g.add("meshes",
        {{"primitives", json::array({{{"attributes", {{"POSITION", g.floats(p, "VEC3", 8)}}},
                                      {"indices", g.uint16s({0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                                                             2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5},
                                                            "SCALAR", 36)},
                                      {"material", 1}}})}});
  const int times = g.floats({0.0f, 2.0f}, "SCALAR", 2);
  const int slide = g.floats({-4, 3.5f, 0, 4, 3.5f, 0}, "VEC3", 2);
  g.add("cameras", {{"type", "perspective"}, {"perspective", {{"yfov", 0.9}, {"znear", 0.1}}}});
  g.doc["scene"] = 0;
  g.doc["scenes"] = json::array({{{"nodes", {0, 1, 2, 3, 4}}}});
  g.doc["nodes"] = json::array({{{"mesh", 0}},
                                {{"mesh", 1}},
                                {{"mesh", 2}, {"translation", {-4, 3.5, 0}}},
                                {{"mesh", 3}},
                                {{"camera", 0}, {"translation", {0, 2, 7}}, {"rotation", {-0.17365, 0, 0, 0.98481}}}});
  g.doc["animations"] = json::array(
      {{{"samplers", json::array({{{"input", times}, {"output", slide}}})},
        {"channels", json::array({{{"sampler", 0}, {"target", {{"node", 2}, {"path", "translation"}}}}})}}});
  return dir.write("panel_room.gltf", g.text()).string();
}

struct Renders {
  std::array<ImageRGB, 2> last;  // the last frame's radiance, both eyes
};

// `frames` frames at 30 fps of `file` with clips `animation` ("all" or "none"), 1 spp, 3
// bounces, denoised, with or without temporal gradients, on `devices` devices. `each` (optional)
// is called with the pipeline after every frame.
Renders render_run(const std::string& file, const std::string& animation, unsigned w, unsigned h, unsigned frames,
                   bool gradients, int devices, const std::function<void(StereoPipeline&, unsigned)>& each = nullptr,
                   DirectLight direct_light = DirectLight::Power) {
  DeviceSet set = DeviceSet::create({devices, DeviceMode::Auto, "", std::nullopt});
  LoadedScene loaded = load_and_build(file, true);
  DeviceScene ds(set, loaded.scene, loaded.bvh);
  SceneAnimator animator(loaded.scene, animation);
  StereoPipeline::Options opt;
  opt.trace.spp = 1;
  opt.trace.bounces = 3;
  opt.denoise->temporal_gradients = gradients;
  opt.trace.direct_light = direct_light;
  StereoPipeline p(set, ds, loaded.scene, w, h, opt);
  for (unsigned f = 0; f < frames; ++f) {
    const double t = f / 30.0;
    animator.update(t, set, ds);
    p.render(f, static_cast<float>(t));
    if (each) each(p, f);
  }
  return {p.radiance()};
}

std::array<ImageRGB, 2> reference(const std::string& file, const std::string& animation, double t, unsigned w,
                                  unsigned h, unsigned spp) {
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  LoadedScene loaded = load_and_build(file, true);
  DeviceScene ds(set, loaded.scene, loaded.bvh);
  SceneAnimator animator(loaded.scene, animation);
  animator.update(t, set, ds);
  PathTracer tracer(set, ds, loaded.scene);
  PathTracer::Options ro;
  ro.spp = spp;
  ro.bounces = 3;
  ro.first_sample_on_gbuffer_ray = false;
  return tracer.render_stereo(static_cast<float>(t), 0, w, h, ro);
}

bool same_bits(const ImageRGB& a, const ImageRGB& b) {
  return a.rgb.size() == b.rgb.size() && std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)) == 0;
}

// The case at a test's size: a light sliding over a still room, 1 spp. Without gradients
// the denoiser's history keeps the light where it was (the pool of light and the box's shadow
// trail it): the last frame's error is tens of times the still run's. With them it must stay
// within the bound, both eyes. The figures at the size: docs/measurements.md, Temporal
// gradients.
TEST(TemporalGradients, ALightThatMovesIsFollowed) {
  const TempDir dir;
  const std::string file = panel_room_file(dir);
  const unsigned w = 160, h = 90, frames = 48;
  const double t_end = (frames - 1) / 30.0;
  const auto ref_moving = reference(file, "all", t_end, w, h, 512);
  const auto ref_still = reference(file, "none", t_end, w, h, 512);
  const auto with = render_run(file, "all", w, h, frames, true, 2).last;
  const auto without = render_run(file, "all", w, h, frames, false, 2).last;
  const auto still = render_run(file, "none", w, h, frames, true, 2).last;
  for (int e = 0; e < 2; ++e) {
    const double s = compare_images(still[e], ref_still[e]).rel_mse;
    const double on = compare_images(with[e], ref_moving[e]).rel_mse;
    const double off = compare_images(without[e], ref_moving[e]).rel_mse;
    std::printf("eye %d: relMSE still %.3g, moving with gradients %.3g (x%.2f), without %.3g (x%.2f)\n", e, s, on,
                on / s, off, off / s);
    EXPECT_LE(on, 6.0 * s) << "eye " << e;
    EXPECT_GT(off, 2.0 * on) << "eye " << e << ": the gradients make the difference";
  }
}

// The same with ReSTIR DI: its reservoirs kept from last frame are evaluated where the panel is
// now, and the gradients (whose shades use next-event estimation) still see the light move. Its
// still error is lower than next-event estimation's, so the bound is on the moving error itself:
// no worse than next-event estimation's (light kept where the panel was would be several times it).
TEST(TemporalGradients, ALightThatMovesIsFollowedWithRestir) {
  const TempDir dir;
  const std::string file = panel_room_file(dir);
  const unsigned w = 160, h = 90, frames = 48;
  const double t_end = (frames - 1) / 30.0;
  const auto ref_moving = reference(file, "all", t_end, w, h, 512);
  const auto ref_still = reference(file, "none", t_end, w, h, 512);
  const auto with = render_run(file, "all", w, h, frames, true, 2, nullptr, DirectLight::Restir).last;
  const auto still = render_run(file, "none", w, h, frames, true, 2, nullptr, DirectLight::Restir).last;
  const auto nee = render_run(file, "all", w, h, frames, true, 2).last;
  for (int e = 0; e < 2; ++e) {
    const double s = compare_images(still[e], ref_still[e]).rel_mse;
    const double on = compare_images(with[e], ref_moving[e]).rel_mse;
    const double by_nee = compare_images(nee[e], ref_moving[e]).rel_mse;
    std::printf("eye %d: ReSTIR relMSE still %.3g, moving %.3g (x%.2f); next-event estimation moving %.3g\n", e, s, on,
                on / s, by_nee);
    EXPECT_LE(on, 1.25 * by_nee) << "eye " << e;
  }
}

// Where nothing changes (the room and its light still, the camera still) last frame's paths
// shaded again are the same paths: every valid stratum's two shades agree to the bit, no history
// is dropped or scaled, and the images are those without gradients, to the bit.
TEST(TemporalGradients, NothingChangesWhereNothingChanged) {
  const TempDir dir;
  const std::string file = panel_room_file(dir);
  const unsigned w = 64, h = 36, frames = 4;
  std::size_t valid = 0, strata = 0;
  const auto check = [&](StereoPipeline& p, unsigned f) {
    if (f == 0) return;
    for (int e = 0; e < 2; ++e) {
      const TemporalGradients* g = p.temporal_gradients(0, e);
      ASSERT_NE(g, nullptr);
      std::vector<cl_float4> raw(std::size_t(g->strata_width()) * g->strata_height());
      p.devices().devices()[0].queue.enqueueReadBuffer(g->raw(), CL_TRUE, 0, raw.size() * sizeof(cl_float4),
                                                       raw.data());
      for (const cl_float4& r : raw) {
        ++strata;
        if (r.s[2] <= 0.0f) continue;  // no valid pick (or a black one)
        ++valid;
        EXPECT_EQ(std::memcmp(&r.s[0], &r.s[1], sizeof(float)), 0) << "shade now " << r.s[0] << ", before " << r.s[1];
        EXPECT_EQ(r.s[3], 0.0f);
      }
    }
  };
  const auto with = render_run(file, "none", w, h, frames, true, 1, check).last;
  const auto without = render_run(file, "none", w, h, frames, false, 1).last;
  EXPECT_GT(valid, strata / 2) << "most strata have a lit surface to re-shade";
  for (int e = 0; e < 2; ++e) EXPECT_TRUE(same_bits(with[e], without[e])) << "eye " << e;
}

// The filter against a host evaluation of the same a-trous steps over the same unfiltered strata
// and G-buffer (gradient_filter.cl's rule, written apart here), after a frame in which the light
// moved: the raw strata carry real differences.
TEST(TemporalGradients, TheFilterIsTheHostsFilter) {
  const TempDir dir;
  const std::string file = panel_room_file(dir);
  const unsigned w = 64, h = 36, frames = 3;
  unsigned checked = 0;
  const auto check = [&](StereoPipeline& p, unsigned f) {
    if (f + 1 != frames) return;
    for (int e = 0; e < 2; ++e) {
      const TemporalGradients* g = p.temporal_gradients(0, e);
      ASSERT_NE(g, nullptr);
      const unsigned sw = g->strata_width(), sh = g->strata_height();
      std::vector<cl_float4> raw(std::size_t(sw) * sh), got(raw.size());
      auto& q = p.devices().devices()[0].queue;
      q.enqueueReadBuffer(g->raw(), CL_TRUE, 0, raw.size() * sizeof(cl_float4), raw.data());
      q.enqueueReadBuffer(g->lambda(), CL_TRUE, 0, got.size() * sizeof(cl_float4), got.data());
      const std::vector<GBufferTexel> gb = p.gbuffer_of(e);
      auto texel = [&](int sx, int sy) -> const GBufferTexel& {
        const int x = std::min(sx * 3 + 1, int(w) - 1), y = std::min(sy * 3 + 1, int(h) - 1);
        return gb[std::size_t(y) * w + std::size_t(x)];
      };
      auto weight = [&](const GBufferTexel& c, const GBufferTexel& t) {
        const bool cm = c.material_class == PX_CLASS_MISS, tm = t.material_class == PX_CLASS_MISS;
        if (cm || tm) return cm && tm ? 1.0 : 0.0;
        const double cosine = std::max(0.0, double(c.normal[0]) * t.normal[0] + double(c.normal[1]) * t.normal[1] +
                                                double(c.normal[2]) * t.normal[2]);
        const double dz = std::abs(double(c.depth) - t.depth) / (0.1 * std::max(std::min(c.depth, t.depth), 1e-6f));
        return dz < 1.0 ? std::pow(cosine, 32.0) * (1.0 - dz) : 0.0;
      };
      std::vector<std::array<double, 4>> cur(raw.size()), next(raw.size());
      for (std::size_t i = 0; i < raw.size(); ++i)
        for (int c = 0; c < 4; ++c) cur[i][c] = raw[i].s[c];
      for (int step : {1, 2, 4}) {
        for (int sy = 0; sy < int(sh); ++sy)
          for (int sx = 0; sx < int(sw); ++sx) {
            std::array<double, 4> sum{};
            double wsum = 0.0;
            for (int dy = -1; dy <= 1; ++dy)
              for (int dx = -1; dx <= 1; ++dx) {
                const int tx = sx + dx * step, ty = sy + dy * step;
                if (tx < 0 || ty < 0 || tx >= int(sw) || ty >= int(sh)) continue;
                const double k = (dx == 0 ? 2.0 : 1.0) * (dy == 0 ? 2.0 : 1.0);
                const double wt = k * weight(texel(sx, sy), texel(tx, ty));
                if (wt <= 0.0) continue;
                for (int c = 0; c < 4; ++c) sum[c] += wt * cur[std::size_t(ty) * sw + tx][c];
                wsum += wt;
              }
            for (int c = 0; c < 4; ++c) next[std::size_t(sy) * sw + sx][c] = wsum > 0.0 ? sum[c] / wsum : 0.0;
          }
        cur.swap(next);
      }
      double changed = 0.0;
      for (std::size_t i = 0; i < raw.size(); ++i) {
        changed += raw[i].s[3];
        for (int c = 0; c < 4; ++c)
          EXPECT_NEAR(got[i].s[c], cur[i][c], 1e-4 * (1.0 + std::abs(cur[i][c])))
              << "stratum " << i << " channel " << c;
      }
      EXPECT_GT(changed, 0.0) << "eye " << e << ": the light moved, some strata saw it";
      ++checked;
    }
  };
  render_run(file, "all", w, h, frames, true, 1, check);
  EXPECT_EQ(checked, 2u);
}

// The gradients' strata cross strip borders through the halo rows: 2, 3 and 4 devices give the
// one-device images to the bit while the light moves, and those images are not the ones without
// gradients (the gradients act).
TEST(TemporalGradients, DevicesGiveOneDevicesImages) {
  const TempDir dir;
  const std::string file = panel_room_file(dir);
  const unsigned w = 64, h = 48, frames = 4;
  const auto one = render_run(file, "all", w, h, frames, true, 1).last;
  const auto off = render_run(file, "all", w, h, frames, false, 1).last;
  EXPECT_FALSE(same_bits(one[0], off[0]));
  for (int n : {2, 3, 4}) {
    const auto many = render_run(file, "all", w, h, frames, true, n).last;
    for (int e = 0; e < 2; ++e) EXPECT_TRUE(same_bits(one[e], many[e])) << n << " devices, eye " << e;
  }
}

}  // namespace
}  // namespace px
