// Converged images for error figures: progressive passes of the path tracer with fresh samples
// each (the sample offset advances), accumulated in double so thousands of samples lose no
// precision. Used by `parallax reference` and the benchmarks.
#pragma once

#include "render/path_tracer.h"

#include <functional>

namespace px {

struct ReferenceOptions {
  unsigned spp = 4096;
  unsigned pass_spp = 64;
  unsigned bounces = PathTracer::Options{}.bounces;  // the renderer's default path length
  std::uint32_t seed = 0x5eed;                       // differs from the default render seed: independent samples
  // How NEE picks emissive triangles: power or tree converge to the same image; restir is refused
  // (render_reference throws std::invalid_argument): a reference stays plain path tracing.
  DirectLight direct_light = PathTracer::Options{}.direct_light;
  // Polled after each pass: true stops early (Ctrl-C), and the images average the passes done.
  std::function<bool()> stop;
};

// Called after each pass with (samples done, samples total).
using ReferenceProgress = std::function<void(unsigned, unsigned)>;

std::array<ImageRGB, 2> render_reference(PathTracer& tracer, float time_s, std::uint32_t frame, unsigned width,
                                         unsigned height, const ReferenceOptions& options,
                                         const ReferenceProgress& progress = {}, unsigned* spp_done = nullptr);

// A progress callback printing "\r[label] done/total spp, elapsed, ~remaining" on stderr.
ReferenceProgress eta_printer(const std::string& label);

}  // namespace px
