#include "pipeline/stages/svgf_denoiser.h"

#include "cl/launch.h"

#include <algorithm>
#include <iterator>
#include <stdexcept>
#include <string>

namespace px {

SvgfDenoiser::SvgfDenoiser(DeviceSet& devices, int device, unsigned width, unsigned height, const Options& options,
                           QueueLanes* lanes)
    : devices_(devices),
      device_(device),
      lanes_(lanes),
      width_(width),
      height_(height),
      options_(options),
      atrous_lanes_(resolve_atrous_lanes(options, devices.devices()[device])),
      atrous_tiles_(atrous_lanes_ == 1 &&
                    (options.atrous_tiles < 0 ? devices.devices()[device].is_gpu() : options.atrous_tiles != 0)) {
  const std::size_t bytes = static_cast<std::size_t>(width) * height * sizeof(cl_float4);
  const auto& ctx = devices.context();
  auto& q = devices.devices()[device].queue;
  const cl_float4 zero{{0, 0, 0, 0}};
  for (int k = 0; k < 2; ++k) {
    illum_[k] = cl::Buffer(ctx, CL_MEM_READ_WRITE, bytes);
    hist_illum_[k] = cl::Buffer(ctx, CL_MEM_READ_WRITE, bytes);
    hist_moments_[k] = cl::Buffer(ctx, CL_MEM_READ_WRITE, bytes);
    hist_resolved_[k] = cl::Buffer(ctx, CL_MEM_READ_WRITE, bytes);
    q.enqueueFillBuffer(hist_resolved_[k], zero, 0, bytes);
    q.enqueueFillBuffer(hist_illum_[k], zero, 0, bytes);
    q.enqueueFillBuffer(hist_moments_[k], zero, 0, bytes);
  }
  moments_ = cl::Buffer(ctx, CL_MEM_READ_WRITE, bytes);
  q.enqueueFillBuffer(moments_, zero, 0, bytes);
  guide_ = cl::Buffer(ctx, CL_MEM_READ_WRITE, bytes);
  luma_ = cl::Buffer(ctx, CL_MEM_READ_WRITE, static_cast<std::size_t>(width) * height * sizeof(cl_float2));
  q.enqueueFillBuffer(guide_, zero, 0, bytes);  // rows never guided read as "not filtered"
}

void SvgfDenoiser::guide(const cl::Buffer& gbuf, RowRange rows) {
  if (rows.size() == 0) return;
  cl::Kernel k(devices_.program("denoise/svgf_temporal.cl"), "svgf_guide");
  k.setArg(0, guide_);
  k.setArg(1, gbuf);
  k.setArg(2, params(rows, rows, 1));
  launch(k, rows, "guide");
}

SvgfParams SvgfDenoiser::params(RowRange rows, RowRange readable, unsigned step, const CameraParams* cam) const {
  SvgfParams p{};
  p.sigma_l = options_.sigma_l;
  p.sigma_z = options_.sigma_z;
  p.sigma_n = options_.sigma_n;
  p.alpha = options_.alpha;
  p.alpha_moments = options_.alpha_moments;
  p.max_history = options_.max_history;
  p.temporal_rows = options_.temporal_rows;
  p.step = step;
  p.row0 = rows.begin;
  p.rows = rows.size();
  p.lo_row = readable.begin;
  p.hi_row = readable.end;
  p.width = width_;
  p.height = height_;
  // Where in its pixel each G-buffer texel of `cam`'s frame lies (the passes that reproject).
  p.jitter[0] = cam ? cam->jitter[0] : 0.5f;
  p.jitter[1] = cam ? cam->jitter[1] : 0.5f;
  return p;
}

namespace {

// Timeline names of the a-trous passes (static strings: the event log keeps pointers).
const char* atrous_pass_name(unsigned iteration) {
  static const char* const names[] = {"a-trous 1", "a-trous 2", "a-trous 3", "a-trous 4",
                                      "a-trous 5", "a-trous 6", "a-trous 7", "a-trous 8"};
  return iteration < std::size(names) ? names[iteration] : "a-trous";
}

}  // namespace

unsigned SvgfDenoiser::resolve_atrous_lanes(const Options& options, const ComputeDevice& device) {
  if (options.atrous_lanes == 1 || options.atrous_lanes == 8) return options.atrous_lanes;
  if (options.atrous_lanes != 0)
    throw std::invalid_argument("SvgfDenoiser: atrous_lanes must be 0, 1 or 8, not " +
                                std::to_string(options.atrous_lanes));
  // Measured on PoCL: see svgf_atrous8 in kernels/denoise/svgf_atrous.cl. A GPU work-item is already a
  // SIMD lane, and eight pixels per item would leave the GPU an eighth of the items.
  return device.is_cpu() ? 8u : 1u;
}

void SvgfDenoiser::launch(cl::Kernel& k, RowRange rows, const char* pass, unsigned pixels_per_item) {
  const std::size_t per_row = (width_ + pixels_per_item - 1) / pixels_per_item;
  events_.push_back({Stage::Denoise, launch_1d(queue(), k, static_cast<std::size_t>(rows.size()) * per_row), pass});
}

void SvgfDenoiser::copy_rows(const cl::Buffer& from, const cl::Buffer& to, RowRange rows, Stage stage,
                             const char* pass) {
  cl::Event e;
  const std::size_t off = static_cast<std::size_t>(rows.begin) * width_ * sizeof(cl_float4);
  const std::size_t len = static_cast<std::size_t>(rows.size()) * width_ * sizeof(cl_float4);
  queue().enqueueCopyBuffer(from, to, off, off, len, nullptr, &e);
  events_.push_back({stage, e, pass});
}

void SvgfDenoiser::temporal(const cl::Buffer& color, const cl::Buffer& albedo, const cl::Buffer& gbuf,
                            const cl::Buffer& prev_gbuf, const CameraParams& cam, const CameraParams& prev_cam,
                            RowRange rows, RowRange readable, const cl::Buffer* scene_motion,
                            const cl::Buffer* scene_instances) {
  if (rows.size() == 0) return;
  motion_this_frame_ = scene_motion != nullptr;
  prev_gbuf_ = &prev_gbuf;
  scene_motion_ = scene_motion;
  scene_instances_ = scene_instances;
  if (scene_motion) {
    if (!motion_())
      motion_ = cl::Buffer(devices_.context(), CL_MEM_READ_WRITE,
                           static_cast<std::size_t>(width_) * height_ * sizeof(cl_float4));
    cl::Kernel km(devices_.program("pipeline/motion.cl"), "gbuffer_motion");
    km.setArg(0, motion_);
    km.setArg(1, gbuf);
    km.setArg(2, *scene_motion);
    set_optional_buffer(km, 3, scene_instances);
    // Anti-aliasing reads the motion of the rows beside its own too (moving silhouettes), the
    // temporal pass that of rows up to PX_SVGF_NEAR_MOTION_REACH away (history beside motion).
    const RowRange wide = widen(rows, std::max(1, PX_SVGF_NEAR_MOTION_REACH), height_);
    const RowRange covered{std::max(wide.begin, readable.begin), std::min(wide.end, readable.end)};
    km.setArg(4, static_cast<cl_uint>(covered.begin));
    km.setArg(5, static_cast<cl_uint>(covered.size()));
    km.setArg(6, static_cast<cl_uint>(width_));
    launch(km, covered, "motion");
  }
  cl::Kernel k(devices_.program("denoise/svgf_temporal.cl"), "svgf_temporal");
  current_ = 0;
  k.setArg(0, illum_[0]);
  k.setArg(1, moments_);
  k.setArg(2, color);
  k.setArg(3, albedo);
  k.setArg(4, gbuf);
  k.setArg(5, prev_gbuf);
  k.setArg(6, hist_illum_[1 - frame_parity_]);
  k.setArg(7, hist_moments_[1 - frame_parity_]);
  const SvgfParams p = params(rows, readable, 1, &cam);
  k.setArg(8, p);
  k.setArg(9, prev_cam);
  k.setArg(10, static_cast<cl_uint>(have_history_));
  k.setArg(11, guide_);  // guide() has run: silhouette pixels look for a neighbour to borrow from
  set_optional_buffer(k, 12, motion_this_frame_ ? &motion_ : nullptr);
  set_optional_buffer(k, 13, gradient_);
  launch(k, rows, "temporal");
  // The moments (with history length) are this frame's moment history as they stand.
  copy_rows(moments_, hist_moments_[frame_parity_], rows, Stage::RecordPrevious, "moment history");
}

void SvgfDenoiser::variance(RowRange rows, RowRange readable) {
  if (rows.size() == 0) return;
  cl::Kernel k(devices_.program("denoise/svgf_temporal.cl"), "svgf_variance");
  k.setArg(0, illum_[1 - current_]);
  k.setArg(1, illum_[current_]);
  k.setArg(2, moments_);
  k.setArg(3, guide_);
  k.setArg(4, params(rows, readable, 1));
  launch(k, rows, "variance");
  // The colour history: this pass's output, the blend of history and this frame (with the
  // spatial estimate for short histories), before any a-trous step. The SVGF paper feeds back
  // the first a-trous step instead; that compounds the step's blur and whatever energy it loses
  // into every later frame (atrium, 1 spp, 16 frames: 0.5 dB lower PSNR, still or moving).
  copy_rows(illum_[1 - current_], hist_illum_[frame_parity_], rows, Stage::RecordPrevious, "colour history");
  current_ = 1 - current_;
}

void SvgfDenoiser::atrous(unsigned iteration, RowRange rows, RowRange readable) {
  if (rows.size() == 0) return;
  const unsigned step = 1u << iteration;
  const bool tiled = atrous_tiles_ && step <= PX_ATROUS_TILE_MAX_STEP;
  // The luminance guide of every row the taps reach (those of the readable rows).
  const RowRange reach = widen(rows, 2 * step, height_);
  const RowRange guided{std::max(reach.begin, readable.begin), std::min(reach.end, readable.end)};
  cl::Kernel kl(devices_.program("denoise/svgf_atrous.cl"), "svgf_luma");
  kl.setArg(0, luma_);
  kl.setArg(1, illum_[current_]);
  kl.setArg(2, guide_);
  kl.setArg(3, params(guided, readable, step));
  launch(kl, guided, "luminance guide");
  cl::Kernel k(devices_.program("denoise/svgf_atrous.cl"), atrous_lanes_ == 8 ? "svgf_atrous8"
                                                           : tiled            ? "svgf_atrous_tiled"
                                                                              : "svgf_atrous");
  k.setArg(0, illum_[1 - current_]);
  k.setArg(1, illum_[current_]);
  k.setArg(2, guide_);
  k.setArg(3, moments_);
  k.setArg(4, luma_);
  k.setArg(5, params(rows, readable, step));
  if (tiled) {
    const std::size_t tiles = static_cast<std::size_t>((width_ + PX_ATROUS_TILE - 1) / PX_ATROUS_TILE) *
                              ((rows.size() + PX_ATROUS_TILE - 1) / PX_ATROUS_TILE);
    events_.push_back({Stage::Denoise, launch_1d(queue(), k, tiles * PX_LOCAL_SIZE), atrous_pass_name(iteration)});
  } else {
    launch(k, rows, atrous_pass_name(iteration), atrous_lanes_);
  }
  current_ = 1 - current_;
}

void SvgfDenoiser::remodulate(const cl::Buffer& out_color, const cl::Buffer& albedo, RowRange rows, RowRange readable) {
  if (rows.size() == 0) return;
  cl::Kernel k(devices_.program("denoise/svgf_atrous.cl"), "svgf_remodulate");
  k.setArg(0, out_color);
  k.setArg(1, illum_[current_]);
  k.setArg(2, moments_);
  k.setArg(3, albedo);
  k.setArg(4, guide_);
  k.setArg(5, params(rows, readable, 1));
  launch(k, rows, "remodulate");
}

void SvgfDenoiser::antialias(const cl::Buffer& out_color, const cl::Buffer& gbuf, const CameraParams& cam,
                             const CameraParams& prev_cam, RowRange rows, RowRange readable) {
  if (rows.size() == 0 || !(options_.taa_alpha < 1.0f)) return;
  // The filter buffer remodulate() did not read is free: the result goes there first, since
  // the pass reads its input's neighbours.
  const cl::Buffer& resolved = illum_[1 - current_];
  cl::Kernel k(devices_.program("denoise/svgf_antialias.cl"), "svgf_antialias");
  const SvgfParams p = params(rows, readable, 1, &cam);
  k.setArg(0, resolved);
  k.setArg(1, hist_resolved_[frame_parity_]);
  k.setArg(2, out_color);
  k.setArg(3, hist_resolved_[1 - frame_parity_]);
  k.setArg(4, gbuf);
  k.setArg(5, p);
  k.setArg(6, prev_cam);
  k.setArg(7, static_cast<cl_uint>(have_history_));
  k.setArg(8, options_.taa_alpha);
  // The motion pass covered temporal()'s rows, which are these (the strip).
  set_optional_buffer(k, 9, motion_this_frame_ ? &motion_ : nullptr);
  if (motion_this_frame_)
    k.setArg(10, *prev_gbuf_);
  else
    set_optional_buffer(k, 10, nullptr);
  set_optional_buffer(k, 11, motion_this_frame_ ? scene_motion_ : nullptr);
  set_optional_buffer(k, 12, motion_this_frame_ ? scene_instances_ : nullptr);
  set_optional_buffer(k, 13, gradient_);
  launch(k, rows, "anti-aliasing");
  copy_rows(resolved, out_color, rows, Stage::Denoise, "anti-aliased copy");
}

void SvgfDenoiser::seam_filter(const cl::Buffer& color, RowRange rows, RowRange readable, int seam_above,
                               int seam_below, int band) {
  if (rows.size() == 0) return;
  cl::Kernel k(devices_.program("denoise/seam_bilateral.cl"), "seam_bilateral");
  const cl::Buffer& scratch = illum_[1 - current_];
  k.setArg(0, scratch);
  k.setArg(1, color);
  k.setArg(2, guide_);
  k.setArg(3, params(rows, readable, 1));
  k.setArg(4, static_cast<cl_int>(seam_above));
  k.setArg(5, static_cast<cl_int>(seam_below));
  k.setArg(6, static_cast<cl_int>(band));
  launch(k, rows, "seam filter");
  copy_rows(scratch, color, rows, Stage::Denoise, "seam filter copy");
}

void SvgfDenoiser::end_frame() {
  frame_parity_ = 1 - frame_parity_;
  have_history_ = true;
}

std::vector<SvgfDenoiser::PassEvent> SvgfDenoiser::take_events() {
  std::vector<PassEvent> out;
  out.swap(events_);
  return out;
}

}  // namespace px
