// SVGF (stage 6) for one eye on one device (kernels/denoise/svgf_*.cl). It owns the filter's
// working buffers and the temporal history, and exposes each pass separately so the pipeline
// can exchange halo rows with neighbouring devices between passes (seam-free mode). All
// buffers are full-frame; each pass writes `rows` and reads only `readable` rows.
#pragma once

#include "cl/device_set.h"
#include "denoise/svgf_constants.h"
#include "image/row_range.h"
#include "pipeline/queue_lanes.h"
#include "pipeline/stage.h"
#include "shared/types.h"

namespace px {

class SvgfDenoiser {
 public:
  struct Options {
    unsigned iterations = 5;  // a-trous steps (spacing 1, 2, 4, ...)
    float sigma_l = 4.0f;     // luminance edge-stopping (SVGF paper default)
    float sigma_z = 1.0f;     // depth
    float sigma_n = 128.0f;   // normal
    float alpha = 0.2f;       // colour blend floor (paper 0.2)
    float alpha_moments = 0.2f;
    unsigned max_history = 32;
    // Temporal anti-aliasing after remodulation (antialias()): the blend floor of the current
    // frame; 1 turns it off.
    float taa_alpha = 0.1f;
    unsigned temporal_rows = 16;  // largest vertical history offset (rows) still accepted
    // Pixels per work-item of the a-trous passes: 1 (svgf_atrous) or 8 (svgf_atrous8, float8
    // arithmetic across eight pixels, for CPUs); 0 picks 8 on CPU devices and 1 elsewhere.
    unsigned atrous_lanes = 0;
    // With a pixel per work-item: the a-trous steps of spacing 1, 2 and 4 read their taps from
    // local-memory tiles (svgf_atrous_tiled; same filter). -1 picks them on GPU devices, 0 never,
    // 1 always (CPUs too: the tests run them on PoCL).
    int atrous_tiles = -1;
  };

  // `device` is a local device index; `lanes` (optional) the pipeline's queue lanes, whose
  // selected lane the passes are enqueued on (without: the device's queue).
  SvgfDenoiser(DeviceSet& devices, int device, unsigned width, unsigned height, const Options& options,
               QueueLanes* lanes = nullptr);

  // Pass 0: the guide texels (normal, signed depth) of G-buffer rows `rows`, which must cover
  // every row the spatial passes of this frame read: the strip and its readable margin.
  void guide(const cl::Buffer& gbuf, RowRange rows);
  // Pass 1 (after guide()): demodulate `color` by `albedo` (float4, the path tracer's
  // per-pixel mean primary albedo, w = the share of samples on filtered surfaces), blend with
  // history reprojected through `prev_cam`. `cam` is the camera `gbuf` was traced with: its
  // jitter (where in each pixel the texel lies) is taken back out of the reprojection.
  // `scene_motion` (an animated scene's DeviceSceneBuffers::motion, else null): the history is
  // found where each pixel's surface point was in the previous frame, through its object's
  // motion as well as the camera's (a motion pass, kernels/pipeline/motion.cl, over `rows`).
  // `scene_instances` (the scene's instance buffer, DeviceSceneBuffers::instances; null for none):
  // a point on an instance's mesh moves with the instance.
  void temporal(const cl::Buffer& color, const cl::Buffer& albedo, const cl::Buffer& gbuf, const cl::Buffer& prev_gbuf,
                const CameraParams& cam, const CameraParams& prev_cam, RowRange rows, RowRange readable,
                const cl::Buffer* scene_motion = nullptr, const cl::Buffer* scene_instances = nullptr);
  // Pass 2: variance from moments (spatial estimate for short histories). Its output, before
  // any a-trous step, is also next frame's colour history.
  void variance(RowRange rows, RowRange readable);
  // Pass 3+i: one a-trous step. It first prefilters the luminance its edge-stopping compares (svgf_luma) over the rows
  // its taps reach, `rows` widened by 2 x 2^i within `readable`, which reads one row farther: in halo mode the input's
  // rows within 2^(i+1) + 1 of the strip must have been exchanged.
  void atrous(unsigned iteration, RowRange rows, RowRange readable);
  // Last pass: remodulate by the same `albedo` into `out_color` (float4 radiance, w its sample
  // count on input: the colour passed to temporal()). Silhouette pixels that borrowed a
  // neighbour's geometry blend with the environment around them in `readable` rows.
  void remodulate(const cl::Buffer& out_color, const cl::Buffer& albedo, RowRange rows, RowRange readable);
  // After remodulate(): temporal anti-aliasing of `out_color` (svgf_antialias) with last
  // frame's result, reprojected through `gbuf` (traced with `cam`) into `prev_cam`. Reads
  // `out_color` within 1 row of `rows` (readable ones) and history within temporal_rows.
  // Nothing with Options::taa_alpha >= 1. Follows object motion where temporal() was given it,
  // and on a moving object's silhouette the object's edge (svgf_antialias).
  void antialias(const cl::Buffer& out_color, const cl::Buffer& gbuf, const CameraParams& cam,
                 const CameraParams& prev_cam, RowRange rows, RowRange readable);
  // The paper's bilateral seam filter on `color` (rows within `band` of a seam; -1 = none),
  // reading rows across the seam (exchanged beforehand).
  void seam_filter(const cl::Buffer& color, RowRange rows, RowRange readable, int seam_above, int seam_below, int band);
  // The temporal gradients of this frame (TemporalGradients::lambda(): a float4 per stratum) that
  // temporal() and antialias() drop history by; null: none (histories as without gradients).
  void set_gradient(const cl::Buffer* gradient) { gradient_ = gradient; }
  // Stage 7: this frame's history becomes the previous frame's (call once per frame, after all
  // devices finished reading the previous history).
  void end_frame();

  // Buffers a halo exchange copies rows of.
  const cl::Buffer& illum() const { return illum_[current_]; }  // input of the next pass
  const cl::Buffer& moments() const { return moments_; }
  const cl::Buffer& history_illum_prev() const { return hist_illum_[1 - frame_parity_]; }
  const cl::Buffer& history_moments_prev() const { return hist_moments_[1 - frame_parity_]; }
  const cl::Buffer& history_resolved_prev() const { return hist_resolved_[1 - frame_parity_]; }

  // Events of this frame's passes, by stage and pass name, for the timeline.
  struct PassEvent {
    Stage stage;
    cl::Event event;
    const char* pass;  // "temporal", "variance", "a-trous 1".., "remodulate", ...
  };
  std::vector<PassEvent> take_events();

  const Options& options() const { return options_; }

 private:
  // `cam`: the camera of this frame's G-buffer, whose jitter the reprojecting passes take out.
  SvgfParams params(RowRange rows, RowRange readable, unsigned step, const CameraParams* cam = nullptr) const;
  void launch(cl::Kernel& k, RowRange rows, const char* pass, unsigned pixels_per_item = 1);
  // Copies rows `rows` of one float4 full-frame buffer into another, timed as `pass` of `stage`.
  void copy_rows(const cl::Buffer& from, const cl::Buffer& to, RowRange rows, Stage stage, const char* pass);
  // options.atrous_lanes with 0 resolved for `device` (invalid values throw).
  static unsigned resolve_atrous_lanes(const Options& options, const ComputeDevice& device);
  cl::CommandQueue& queue() { return lanes_ ? lanes_->queue(device_) : devices_.devices()[device_].queue; }

  DeviceSet& devices_;
  int device_;
  QueueLanes* lanes_;
  unsigned width_, height_;
  Options options_;
  unsigned atrous_lanes_;     // pixels per work-item of the a-trous passes on this device (1 or 8)
  bool atrous_tiles_;         // svgf_atrous_tiled for the small steps (atrous_lanes_ 1 only)
  cl::Buffer illum_[2];       // ping-pong filter buffers (rgb, variance)
  cl::Buffer moments_;        // (m1, m2, history length, filtered flag)
  cl::Buffer guide_;          // (normal, +depth filtered / -depth not), from guide()
  cl::Buffer luma_;           // float2 per pixel: what an a-trous step's luminance test compares (svgf_luma)
  cl::Buffer hist_illum_[2];  // colour history: [frame_parity_] written this frame
  cl::Buffer hist_moments_[2];
  cl::Buffer hist_resolved_[2];  // anti-aliased radiance (rgb, history length), as hist_illum_
  cl::Buffer motion_;            // float4 per pixel: the previous frame's surface point (motion.cl)
  bool motion_this_frame_ = false;
  // This frame's previous G-buffer and the scene's triangle motion, from temporal() for
  // antialias()'s moving silhouettes (null: a static scene).
  const cl::Buffer* prev_gbuf_ = nullptr;
  const cl::Buffer* scene_motion_ = nullptr;
  const cl::Buffer* scene_instances_ = nullptr;
  const cl::Buffer* gradient_ = nullptr;  // set_gradient()
  int current_ = 0;
  int frame_parity_ = 0;
  bool have_history_ = false;
  std::vector<PassEvent> events_;
};

}  // namespace px
