#include "render/reference_render.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <stdexcept>

namespace px {

std::array<ImageRGB, 2> render_reference(PathTracer& tracer, float time_s, std::uint32_t frame, unsigned width,
                                         unsigned height, const ReferenceOptions& options,
                                         const ReferenceProgress& progress, unsigned* spp_done) {
  if (options.spp == 0 || options.pass_spp == 0) throw std::invalid_argument("reference spp must be at least 1");
  PathTracer::Options opt;
  opt.bounces = options.bounces;
  opt.seed = options.seed;
  if (options.direct_light == DirectLight::Restir)
    throw std::invalid_argument(
        "reference: --direct-light restir is not for references (plain path tracing: power or "
        "tree)");
  opt.direct_light = options.direct_light;
  opt.first_sample_on_gbuffer_ray = false;  // the whole pixel, every sample jittered
  std::array<std::vector<double>, 2> sum;
  for (auto& s : sum) s.assign(static_cast<std::size_t>(width) * height * 3, 0.0);
  unsigned done = 0;
  while (done < options.spp) {
    opt.spp = std::min(options.pass_spp, options.spp - done);
    auto eyes = tracer.render_stereo(time_s, frame, width, height, opt, done);
    for (int e = 0; e < 2; ++e)
      for (std::size_t i = 0; i < sum[e].size(); ++i) sum[e][i] += static_cast<double>(eyes[e].rgb[i]) * opt.spp;
    done += opt.spp;
    if (progress) progress(done, options.spp);
    if (options.stop && done < options.spp && options.stop()) break;
  }
  if (spp_done) *spp_done = done;
  std::array<ImageRGB, 2> out;
  for (int e = 0; e < 2; ++e) {
    out[e].width = static_cast<int>(width);
    out[e].height = static_cast<int>(height);
    out[e].rgb.resize(sum[e].size());
    for (std::size_t i = 0; i < sum[e].size(); ++i) out[e].rgb[i] = static_cast<float>(sum[e][i] / done);
  }
  return out;
}

ReferenceProgress eta_printer(const std::string& label) {
  auto start = std::make_shared<std::chrono::steady_clock::time_point>(std::chrono::steady_clock::now());
  return [label, start](unsigned done, unsigned total) {
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - *start).count();
    std::fprintf(stderr, "\r[%s] %u/%u spp, %.0f s elapsed, about %.0f s left   ", label.c_str(), done, total, s,
                 s / done * (total - done));
    if (done == total) std::fprintf(stderr, "\n");
  };
}

}  // namespace px
