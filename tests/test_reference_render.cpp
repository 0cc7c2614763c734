// render_reference, the ground truth behind every PSNR figure: its progressive passes must draw
// new samples and average them as one render of all the samples would, and the result must be
// the analytic answer of a furnace, with a variance (and an error) falling as 1 / spp.
#include "bvh/bvh_builder.h"
#include "bvh/flat_bvh.h"
#include "cl/device_set.h"
#include "render/device_scene.h"
#include "render/path_tracer.h"
#include "render/reference_render.h"
#include "scene/primitives.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <stdexcept>
#include <utility>
#include <vector>

namespace px {
namespace {

DeviceSet& one_device() {
  static DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  return set;
}

// Inside a closed sphere whose surface is diffuse of albedo a and emits le (from both faces),
// radiance is the same everywhere and in every direction, order by order: the path's k-th
// surface after the camera ray contributes a^k le. The renderer adds the emission of the
// surfaces met at bounces 0 .. B (B = Options::bounces: the vertex at bounce B adds its
// emission, by BSDF hit or by the previous vertex's next-event estimation, and ends the path),
// and Russian roulette is unbiased, so every pixel converges to
//   L_B = le (1 + a + ... + a^B) = le (1 - a^(B+1)) / (1 - a).
// Roulette from bounce 3 on and next-event estimation of the 1280 emitting triangles give each
// path a random value, so the pixels have a real variance to check. The facets are shaded flat:
// with the icosphere's smooth normals the renderer loses a little energy (paths whose sampled
// direction leaves the shading hemisphere's side of the geometric surface end), measured at
// -0.2% of L_8 in every light-sampling mode, ~5 standard errors of the test below; flat, the
// mean is the series to within noise (-0.05%, 1 standard error, at 128 spp on 64 x 48).
constexpr float kAlbedo = 0.75f, kEmission = 0.25f;
constexpr unsigned kBounces = 8;
const double kFurnace = kEmission * (1.0 - std::pow(double(kAlbedo), kBounces + 1)) / (1.0 - kAlbedo);

struct Furnace {
  Scene scene;
  FlatBvh bvh;
  std::unique_ptr<DeviceScene> device_scene;
  std::unique_ptr<PathTracer> tracer;
  Furnace() {
    Material m;
    m.diffuse = glm::vec3(kAlbedo);
    m.emission = glm::vec3(kEmission);
    m.two_sided = true;  // the camera inside sees the faces' backs (outward winding)
    scene.materials.push_back(m);
    append_icosphere(scene.triangles, glm::vec3(0.0f), 1.0f, 3, 0);
    for (auto& t : scene.triangles) {
      glm::vec3 n = glm::normalize(glm::cross(t.p[1] - t.p[0], t.p[2] - t.p[0]));
      if (glm::dot(n, t.p[0] + t.p[1] + t.p[2]) < 0.0f) n = -n;
      t.n[0] = t.n[1] = t.n[2] = n;
    }
    scene.camera.position = glm::vec3(0.0f);
    scene.camera.target = glm::vec3(0.0f, 0.0f, 1.0f);
    scene.camera.vfov_deg = 90.0f;
    bvh = build_bvh(scene.triangles);
    device_scene = std::make_unique<DeviceScene>(one_device(), scene, bvh);
    tracer = std::make_unique<PathTracer>(one_device(), *device_scene, scene);
  }
  std::array<ImageRGB, 2> reference(unsigned w, unsigned h, unsigned spp, unsigned pass_spp, std::uint32_t seed,
                                    const ReferenceProgress& progress = {}, unsigned* done = nullptr,
                                    std::function<bool()> stop = {}) {
    ReferenceOptions opt;
    opt.spp = spp;
    opt.pass_spp = pass_spp;
    opt.bounces = kBounces;
    opt.seed = seed;
    opt.stop = std::move(stop);
    return render_reference(*tracer, 0.0f, 0, w, h, opt, progress, done);
  }
  // One launch of `spp` samples with the reference's settings: what the passes must add up to.
  std::array<ImageRGB, 2> one_launch(unsigned w, unsigned h, unsigned spp, std::uint32_t seed) {
    PathTracer::Options opt;
    opt.spp = spp;
    opt.bounces = kBounces;
    opt.seed = seed;
    opt.first_sample_on_gbuffer_ray = false;
    return tracer->render_stereo(0.0f, 0, w, h, opt);
  }
};

Furnace& furnace() {
  static Furnace f;
  return f;
}

// Channel 0 of every pixel of both eyes: independent estimates (each pixel and eye has its own
// sample stream). The scene is grey, so the other channels repeat it.
std::vector<double> values(const std::array<ImageRGB, 2>& eyes) {
  std::vector<double> v;
  for (const auto& eye : eyes)
    for (std::size_t i = 0; i < eye.rgb.size(); i += 3) v.push_back(eye.rgb[i]);
  return v;
}

struct Stats {
  double mean, variance, mse;  // mse: mean squared difference from the analytic value
};
Stats stats(const std::vector<double>& v, double truth) {
  double s = 0.0, e = 0.0;
  for (double x : v) {
    s += x;
    e += (x - truth) * (x - truth);
  }
  const double m = s / v.size();
  double var = 0.0;
  for (double x : v) var += (x - m) * (x - m);
  return {m, var / (v.size() - 1), e / v.size()};
}

TEST(ReferenceRender, PassesAddUpToOneLaunchOfAllTheSamples) {
  // 10 spp in passes of 4: 4 + 4 + 2. Pass k must trace samples 4k.. of each pixel (not the
  // first ones again), and the average must weight each pass by its samples: then the result is
  // one launch of samples 0..9, up to float rounding. A repeated pass, a division by the pass
  // count, a dropped or mis-weighted last pass all move pixels by far more than that.
  auto& f = furnace();
  const unsigned w = 16, h = 12;
  std::vector<std::pair<unsigned, unsigned>> calls;
  unsigned done = 0;
  const auto passes = f.reference(
      w, h, 10, 4, 77, [&](unsigned d, unsigned t) { calls.emplace_back(d, t); }, &done);
  const auto whole = f.one_launch(w, h, 10, 77);
  EXPECT_EQ(done, 10u);
  EXPECT_EQ(calls, (std::vector<std::pair<unsigned, unsigned>>{{4, 10}, {8, 10}, {10, 10}}));
  for (int e = 0; e < 2; ++e) {
    ASSERT_EQ(passes[e].width, int(w));
    ASSERT_EQ(passes[e].height, int(h));
    ASSERT_EQ(passes[e].rgb.size(), whole[e].rgb.size());
    std::size_t off = 0;
    for (std::size_t i = 0; i < whole[e].rgb.size(); ++i)
      off += std::abs(passes[e].rgb[i] - whole[e].rgb[i]) > 1e-5f * (1.0f + whole[e].rgb[i]);
    EXPECT_EQ(off, 0u) << "eye " << e << ": values differing from one launch of the same 10 samples";
  }
  // And the first pass alone is not that launch: the passes did draw different samples.
  const auto first4 = f.one_launch(w, h, 4, 77);
  std::size_t same = 0;
  for (std::size_t i = 0; i < first4[0].rgb.size(); ++i) same += first4[0].rgb[i] == passes[0].rgb[i];
  EXPECT_LT(same, first4[0].rgb.size() / 10);
  EXPECT_EQ(f.tracer->nonfinite_paths(), 0u);
}

TEST(ReferenceRender, StoppedEarlyItAveragesThePassesDone) {
  auto& f = furnace();
  unsigned done = 0;
  const auto stopped = f.reference(8, 8, 12, 4, 5, {}, &done, [] { return true; });
  EXPECT_EQ(done, 4u);
  const auto first = f.one_launch(8, 8, 4, 5);
  for (int e = 0; e < 2; ++e)
    for (std::size_t i = 0; i < first[e].rgb.size(); ++i)
      ASSERT_NEAR(stopped[e].rgb[i], first[e].rgb[i], 1e-5f * (1.0f + first[e].rgb[i]))
          << "eye " << e << " value " << i;
  EXPECT_THROW(f.reference(8, 8, 0, 4, 5), std::invalid_argument);
  EXPECT_THROW(f.reference(8, 8, 4, 0, 5), std::invalid_argument);
}

TEST(ReferenceRender, FurnaceMeanIsTheSeriesAndVarianceAndErrorFallAsOneOverSpp) {
  // Three independent references (different seeds) of the furnace: 1 spp, then 4 and 16 spp in
  // passes of 2. Every pixel value is an independent estimate of kFurnace, so across the pixels:
  //   - the mean is kFurnace within a few standard errors (no bias; kFurnace with B = 8 is 7.5%
  //     below the infinite series' 1.0, so a bounce counted wrongly shows too);
  //   - the variance of a k-spp reference is sigma^2 / k, sigma^2 the 1-spp variance: passes
  //     that re-used their samples would give sigma^2 / 2 at both 4 and 16 spp;
  //   - the mean squared error against kFurnace falls by 4 from 4 to 16 spp (1 if repeated).
  auto& f = furnace();
  const unsigned w = 48, h = 32;
  const Stats s1 = stats(values(f.reference(w, h, 1, 1, 101)), kFurnace);
  const Stats s4 = stats(values(f.reference(w, h, 4, 2, 202)), kFurnace);
  const auto v16 = values(f.reference(w, h, 16, 2, 303));
  const Stats s16 = stats(v16, kFurnace);
  const double n = static_cast<double>(v16.size());
  for (auto [spp, s] : {std::pair{1u, s1}, {4u, s4}, {16u, s16}}) {
    std::printf("[ measure  ] %2u spp: mean %.5f (series %.5f), variance x spp %.5f, mse x spp %.5f\n", spp, s.mean,
                kFurnace, s.variance * spp, s.mse * spp);
    EXPECT_NEAR(s.mean, kFurnace, 4.5 * std::sqrt(s.variance / n)) << spp << " spp: biased";
  }
  EXPECT_GT(s1.variance, 1e-3) << "the furnace has too little noise to test with";
  // Over 30 seed triples the ratios below spread 0.92..1.06 (variance) and 3.77..4.30 (error);
  // the bands are about 6 of their standard deviations wide, and samples repeated from pass to
  // pass (2 spp each) would give 2 and 8 for the variance ratios and 1 for the error ratio.
  EXPECT_NEAR(s4.variance * 4.0 / s1.variance, 1.0, 0.2) << "4 spp are not 4 independent samples";
  EXPECT_NEAR(s16.variance * 16.0 / s1.variance, 1.0, 0.2) << "16 spp are not 16 independent samples";
  EXPECT_NEAR(s4.mse / s16.mse, 4.0, 0.8) << "error does not fall as 1/spp";
  EXPECT_EQ(f.tracer->nonfinite_paths(), 0u);
}

}  // namespace
}  // namespace px
