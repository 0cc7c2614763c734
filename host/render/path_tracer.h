// Stage 2 (and, for the mono pipeline, the whole right eye): path traces one eye's rows on
// every device, each device its own contiguous strip, and gathers the strips on the host.
// The kernel is kernels/pathtrace/path_trace.cl; this class owns its launch parameters.
#pragma once

#include "cl/device_set.h"
#include "image/image_io.h"
#include "image/row_range.h"
#include "render/device_scene.h"
#include "render/stereo_camera.h"

#include <array>
#include <cstdint>

namespace px {

enum class LightSampling : std::uint32_t { Mis = PX_LIGHTS_MIS, Nee = PX_LIGHTS_NEE, Bsdf = PX_LIGHTS_BSDF };
// How next-event estimation picks an emissive triangle: by power, by the light tree's importance
// at the shading point (kernels/shading/light_tree.h), or ReSTIR DI over the tree's candidates.
enum class DirectLight : std::uint32_t { Power = PX_DIRECT_POWER, Tree = PX_DIRECT_TREE, Restir = PX_DIRECT_RESTIR };

class PathTracer {
 public:
  static constexpr unsigned kMaxBounces = PX_MAX_BOUNCES_LIMIT;

  struct Options {
    unsigned spp = 1;
    unsigned bounces = 6;
    unsigned rr_start_bounce = 3;  // Russian roulette from this bounce on
    LightSampling light_sampling = LightSampling::Mis;
    // The light tree: on the many-lights scene 4.3x power's raw efficiency (1.5x denoised), and
    // within timing noise of it elsewhere (docs/measurements.md, Many lights).
    DirectLight direct_light = DirectLight::Tree;
    std::uint32_t seed = 0;
    // A frame's sample 0 of every pixel goes through the camera's jitter point of the frame
    // (CameraParams::jitter, px_sample_camera_dir): the G-buffer's ray, so the path tracer can write the G-buffer
    // (Targets::gbuffer) and the denoiser's G-buffer describes the surface that sample saw. Off for references, which
    // integrate the whole pixel.
    bool first_sample_on_gbuffer_ray = true;
    // With first_sample_on_gbuffer_ray: every sample along the G-buffer's ray (starting at its hit), not
    // only the first. What a denoised frame at several spp wants (StereoPipeline sets it there): the
    // G-buffer then describes the surface each sample saw, where samples spread over the pixel mixed a
    // lamp into a ceiling texel and the filter darkened it. An undenoised frame keeps its samples
    // spread, its only anti-aliasing.
    bool every_sample_on_gbuffer_ray = false;
    // With first_sample_on_gbuffer_ray and the samples spread: a pixel counts only the samples
    // whose first hit is of its first counted sample's kind, emitter or not
    // (PX_GBUFFER_RAY_FIRST_KIND). What a denoised frame in a moving view wants (StereoPipeline sets
    // it there): the spread samples still smooth edges, but a lamp's no longer falls under a
    // ceiling's texel.
    bool same_kind_samples = false;
  };

  // Everything but buffers that a path_trace / path_trace_list launch needs.
  static FrameParams frame_params(const Scene& scene, std::size_t light_count, const Options& options, int eye,
                                  unsigned row0, unsigned rows, std::uint32_t frame, std::uint32_t sample_offset = 0);

  // The one launch of the path_trace kernel (path_trace_pixels on CPUs), shared by render_stereo and the pipeline's
  // path tracing stage: `rows` of eye `eye` into the full-frame float4 `radiance` and `albedo` buffers (absolute pixel
  // indices; only those rows are written), dropped non-finite paths counted into `nonfinite` (uint). `gbuffer`, if not
  // null: the eye's full-frame G-buffer (GBufferTexel), whose texels of `rows` the first sample (the G-buffer's ray)
  // writes (the G-buffer pass's, bit for bit; needs first_sample_on_gbuffer_ray and sample offset 0). Returns the
  // launch's event.
  struct Targets {
    const cl::Buffer& radiance;
    const cl::Buffer& albedo;
    const cl::Buffer& nonfinite;
    const cl::Buffer* gbuffer = nullptr;
  };
  // Throws std::logic_error for a G-buffer target that the launch would not write (no first
  // sample on the G-buffer's ray in `params`). Both path tracers check it.
  static void check_gbuffer_target(const Targets& out, const FrameParams& params);
  static cl::Event launch(const cl::CommandQueue& queue, const cl::Program& program, const DeviceSceneBuffers& scene,
                          const Targets& out, const FrameParams& params, const CameraParams& camera, unsigned width);
  // The hole filling stage's launch: the `*hole_count` pixels listed in `holes` (absolute pixel
  // indices, launched for `max_items` of them), their first samples started from `gbuffer_hits`
  // (the eye's G-buffer pass's hits) if not null. out.gbuffer must be null.
  static cl::Event launch_list(const cl::CommandQueue& queue, const cl::Program& program,
                               const DeviceSceneBuffers& scene, const Targets& out, const cl::Buffer& holes,
                               const cl::Buffer& hole_count, const cl::Buffer* gbuffer_hits, const FrameParams& params,
                               const CameraParams& camera, std::size_t max_items);

  // Stage 3 on a CPU device, the G-buffer pass in the path tracer's kernel (path_trace_pixels):
  // texels of `params.rows` rows from `params.row0` into the eye's full-frame `gbuffer`, each ray's
  // hit into the full-frame `first_hits` if not null; the texels and hits of gbuffer.cl's `gbuffer`
  // to the bit. `params` from gbuffer_params. Throws std::logic_error on a GPU queue or for other
  // params.
  static FrameParams gbuffer_params(int eye, unsigned row0, unsigned rows, std::uint32_t frame);
  static cl::Event launch_gbuffer(const cl::CommandQueue& queue, const cl::Program& program,
                                  const DeviceSceneBuffers& scene, const cl::Buffer& gbuffer,
                                  const cl::Buffer* first_hits, const FrameParams& params, const CameraParams& camera,
                                  unsigned width);

  // The temporal gradients' shading on a CPU device, in the path tracer's kernel
  // (path_trace_pixels): temporal_gradient.cl's gradient_shade over `params.s_rows` strata rows from
  // `params.s_row0`, to the bit. The buffers are gradient_shade's (TemporalGradients owns them):
  // `raw` per stratum, this frame's and last frame's shades per pixel (`ref`, `prev_ref`), this and
  // last frame's G-buffers, the non-finite counter, the triangles' motion (null for a still scene).
  // `frame` is the shading's FrameParams (its bounces capped). Throws std::logic_error on a GPU
  // queue.
  struct GradientInputs {
    const cl::Buffer& raw;
    const cl::Buffer& ref;
    const cl::Buffer& prev_ref;
    const cl::Buffer& gbuffer;
    const cl::Buffer& prev_gbuffer;
    const cl::Buffer& nonfinite;
    const cl::Buffer* tri_motion = nullptr;
    GradientParams params{};
  };
  static cl::Event launch_gradient(const cl::CommandQueue& queue, const cl::Program& program,
                                   const DeviceSceneBuffers& scene, const GradientInputs& in, const FrameParams& frame,
                                   const CameraParams& camera);

  PathTracer(DeviceSet& devices, const DeviceScene& device_scene, const Scene& scene)
      : devices_(devices), device_scene_(device_scene), scene_(scene) {}

  // Both eyes at `time_s` for frame number `frame` (the frame selects the sample stream).
  // `sample_offset` shifts the sample indices (progressive passes draw new samples).
  std::array<ImageRGB, 2> render_stereo(float time_s, std::uint32_t frame, unsigned width, unsigned height,
                                        const Options& options, std::uint32_t sample_offset = 0);

  // Paths dropped because their radiance was not finite, summed over every launch so far.
  std::uint64_t nonfinite_paths() const { return nonfinite_total_; }
  // Device time of the last render_stereo, per device (ms, from profiling events).
  const std::vector<double>& last_device_ms() const { return last_device_ms_; }

 private:
  DeviceSet& devices_;
  const DeviceScene& device_scene_;
  const Scene& scene_;
  std::uint64_t nonfinite_total_ = 0;
  std::vector<double> last_device_ms_;
};

}  // namespace px
