/* Path tracing megakernel: one work-item per pixel of a strip of rows of one eye, `spp`
 * paths each, next-event estimation and BSDF sampling combined by the power heuristic,
 * Russian roulette from `rr_start_bounce`, at most `max_bounces` bounces.
 *
 * Every random number comes from the counter-based stream keyed by (frame, eye, pixel,
 * sample, dimension), so the result is independent of which device or strip ran the pixel.
 * A path whose radiance is not finite is dropped (left out of the pixel's mean) and counted
 * in `nonfinite`: no NaN or Inf ever reaches the output. */
#include "shared/types.h"
#include "denoise/gradient_stratum.h"
#include "pathtrace/path_vertex.h"
#include "pathtrace/pixel_mean.h"
#include "pathtrace/trace_path.h"
#include "pipeline/gbuffer_pixel.h"
#include "pipeline/gbuffer_texel.h"
#include "render/camera.h"
#include "trace/traverse.h"

/* Sample s of pixel (x, y): the radiance of its camera path, and in *albedo the path's primary
 * demodulation albedo (see px_trace_path). Every random number comes from the pixel's and the
 * sample's own stream, so a sample is the same whichever work-item traces it. If this sample is
 * the G-buffer's ray (through the camera's jitter position): `gbuffer_texel` (if not null) receives the pixel's
 * G-buffer texel. If it goes along that ray (px_sample_along_gbuffer_ray), `gbuffer_hit` (if not null) is the
 * ray's hit, traced already. */
inline float3 px_render_sample(const SceneView* scene, const FrameParams* fp, const CameraParams* cam, uint x, uint y,
                               uint s, float4* albedo, global GBufferTexel* gbuffer_texel,
                               const global Hit* gbuffer_hit) {
  const SampleKey key = px_sample_key(x, y, fp->frame, fp->eye, fp->sample_offset + s, fp->seed);
  const float3 dir = px_sample_camera_dir(fp, cam, key, x, y, s);
  return px_trace_path(scene, fp, px_camera_origin(cam), dir, key, px_restir_lights_first_vertex(fp, s), albedo,
                       px_sample_on_gbuffer_ray(fp, s) ? gbuffer_texel : 0,
                       px_sample_along_gbuffer_ray(fp, s) ? gbuffer_hit : 0);
}

/* Mean radiance of pixel (x, y): fp->spp paths; a path with non-finite radiance is dropped
 * from the mean and counted in *nonfinite. Returns (rgb, finite sample count); *albedo gets
 * the mean primary demodulation albedo of the same (finite) paths, so that radiance / albedo
 * is the pixel's illumination even where the albedo varies inside the pixel (textures,
 * silhouettes, cut-outs); its w is the fraction of those paths whose camera ray met a surface
 * the denoiser filters (the pixel's coverage: SVGF filters a silhouette pixel whose centre
 * misses the object but whose samples hit it). No finite path: (1, 1, 1, 0). */
inline float4 px_render_pixel(const SceneView* scene, const FrameParams* fp, const CameraParams* cam, uint x, uint y,
                              volatile global uint* nonfinite, float4* albedo, global GBufferTexel* gbuffer_texel,
                              const global Hit* gbuffer_hit) {
  float3 sum = (float3)(0.0f, 0.0f, 0.0f);
  float4 albedo_sum = (float4)(0.0f, 0.0f, 0.0f, 0.0f);
  uint good = 0;
  const int same_kind_only = fp->gbuffer_ray_samples == PX_GBUFFER_RAY_FIRST_KIND;
  int first_kind = -1;
  for (uint s = 0; s < fp->spp; ++s) {
    float4 a;
    const float3 l = px_render_sample(scene, fp, cam, x, y, s, &a, gbuffer_texel, gbuffer_hit);
    if (!px_count_sample(&sum, &albedo_sum, &good, &first_kind, same_kind_only, l, a)) atomic_inc(nonfinite);
  }
  return px_pixel_mean(sum, albedo_sum, good, albedo);
}

/* Stage 2 (and mono): every pixel of rows [fp.row0, fp.row0 + fp.rows) of eye fp.eye.
 * out, albedo_out: full-frame float4 images (width * height); only these rows are written.
 * gbuffer: null, or the eye's full-frame G-buffer, whose texels of these rows the first
 * sample writes (the G-buffer pass's, bit for bit; only with fp.gbuffer_ray_samples set and
 * fp.sample_offset 0, else nothing is written). */
kernel void path_trace(global float4* out, global float4* albedo_out, volatile global uint* nonfinite,
                       global GBufferTexel* gbuffer, FrameParams fp, CameraParams cam, PX_SCENE_PARAMS) {
  const uint i = get_global_id(0);
  if (i >= fp.rows * cam.width) return;
  const SceneView scene = PX_SCENE_VIEW();
  const uint p = fp.row0 * cam.width + i;
  float4 albedo;
  out[p] = px_render_pixel(&scene, &fp, &cam, p % cam.width, p / cam.width, nonfinite, &albedo,
                           gbuffer ? gbuffer + p : 0, 0);
  albedo_out[p] = albedo;
}

/* Stage 5, hole filling: only the pixels listed in `holes` (full-frame indices, *hole_count of
 * them, compacted by compact_holes), so work-items do not idle on reprojected pixels. The launch
 * is sized for the worst case; items past the count return at once. `gbuffer_hits`: null, or the
 * G-buffer pass's full-frame hits of the same eye (its rays are the first samples (the G-buffer's rays)'),
 * so that a hole's first sample starts at its hit instead of tracing the ray a second time. */
kernel void path_trace_list(global float4* out, global float4* albedo_out, volatile global uint* nonfinite,
                            const global uint* holes, const global uint* hole_count, const global Hit* gbuffer_hits,
                            FrameParams fp, CameraParams cam, PX_SCENE_PARAMS) {
  const uint i = get_global_id(0);
  if (i >= *hole_count) return;
  const SceneView scene = PX_SCENE_VIEW();
  const uint p = holes[i];
  float4 albedo;
  out[p] = px_render_pixel(&scene, &fp, &cam, p % cam.width, p / cam.width, nonfinite, &albedo, 0,
                           gbuffer_hits ? gbuffer_hits + p : 0);
  albedo_out[p] = albedo;
}

/* Stages 2, 3 and 5 and the temporal gradients' shading in one kernel, for CPU devices; `mode`
 * says which (PX_PIXELS_*).
 *   PATHS: with `holes` null, path_trace (the strip's pixels fp.row0.., G-buffer texels to
 *     `gbuffer`); else path_trace_list (the listed pixels, their first samples from `gbuffer_hits`).
 *   GBUFFER: the G-buffer pass (gbuffer.cl's `gbuffer`) over the rows fp.row0..: each pixel's
 *     G-buffer ray, its texel to `gbuffer`, its hit to `first_hits` (if not null), no radiance or
 *     albedo.
 *   GRADIENT: temporal_gradient.cl's `gradient_shade` over gp's strata rows: `out` is its `raw`,
 *     `albedo_out` its `ref`, `gbuffer` its `gbuf` (read only), and prev_ref, prev_gbuf,
 *     tri_motion and gp its own (unused, null or zero, in the other modes).
 * The pixels, texels, hits and shades are the other kernels' to the bit. PoCL makes a kernel's
 * work-group function and native code at its first launch under one process-wide lock, so a first
 * run waits for each kernel in turn (path_trace_list alone was 0.7 s of it, gbuffer_pairs 0.67 s,
 * gradient_shade 0.6 s); one kernel for the four compiles the path code once. GPUs keep their
 * kernels: each is specialised at build time, and one kernel for all would hold more registers
 * (docs/measurements.md, "One kernel for the left eye and the holes on CPUs", "The G-buffer pass in
 * the path tracer's kernel on CPUs", "The temporal gradients in the path tracer's kernel on CPUs"). */
kernel void path_trace_pixels(global float4* out, global float4* albedo_out, volatile global uint* nonfinite,
                              global GBufferTexel* gbuffer, const global uint* holes, const global uint* hole_count,
                              const global Hit* gbuffer_hits, global Hit* first_hits, uint mode,
                              const global float4* prev_ref, const global GBufferTexel* prev_gbuf,
                              const global float4* tri_motion, GradientParams gp, FrameParams fp, CameraParams cam,
                              PX_SCENE_PARAMS) {
  const uint i = get_global_id(0);
  const SceneView scene = PX_SCENE_VIEW();
  if (mode == PX_PIXELS_GRADIENT) {
    if (i < gp.s_rows * gp.strata_w)
      px_gradient_stratum(&scene, i, out, albedo_out, prev_ref, gbuffer, prev_gbuf, nonfinite, tri_motion, &fp, &cam,
                          &gp);
    return;
  }
  if (i >= (holes ? *hole_count : fp.rows * cam.width)) return;
  const uint p = holes ? holes[i] : fp.row0 * cam.width + i;
  if (mode == PX_PIXELS_GBUFFER) {
    px_gbuffer_pixel(&scene, &cam, p, gbuffer, first_hits);
    return;
  }
  float4 albedo;
  out[p] = px_render_pixel(&scene, &fp, &cam, p % cam.width, p / cam.width, nonfinite, &albedo,
                           gbuffer ? gbuffer + p : 0, gbuffer_hits ? gbuffer_hits + p : 0);
  albedo_out[p] = albedo;
}

/* Stage 5 with the samples spread: one work-item per (hole, sample) pair, so that a launch at
 * spp samples has spp times as many items as holes. At 1280x720 a frame's ~60k holes are too
 * few work-items to fill a large GPU; at 4 spp this gives it 240k. Each item writes its sample
 * (radiance with w = 1 if finite, else all 0; then its albedo) to `samples`, two float4 per
 * pair; resolve_hole_samples averages them. Images are bit-identical to path_trace_list: the
 * same samples, summed in the same order. */
kernel void path_trace_list_samples(global float4* samples, volatile global uint* nonfinite, const global uint* holes,
                                    const global uint* hole_count, const global Hit* gbuffer_hits, FrameParams fp,
                                    CameraParams cam, PX_SCENE_PARAMS) {
  const uint i = get_global_id(0);
  const uint hole = i / fp.spp, s = i % fp.spp;
  if (hole >= *hole_count) return;
  const SceneView scene = PX_SCENE_VIEW();
  const uint p = holes[hole];
  float4 a;
  const float3 l =
      px_render_sample(&scene, &fp, &cam, p % cam.width, p / cam.width, s, &a, 0, gbuffer_hits ? gbuffer_hits + p : 0);
  const int finite = px_finite3(l);
  if (!finite) atomic_inc(nonfinite);
  samples[2u * i] = finite ? (float4)(l, 1.0f) : (float4)(0.0f, 0.0f, 0.0f, 0.0f);
  samples[2u * i + 1u] = a;
}

/* The pixels of path_trace_list_samples: per hole, its spp samples summed in sample order (as
 * px_render_pixel sums them), then the same mean. */
kernel void resolve_hole_samples(global float4* out, global float4* albedo_out, volatile global uint* nonfinite,
                                 const global float4* samples, const global uint* holes, const global uint* hole_count,
                                 uint spp, uint same_kind_only) {
  const uint hole = get_global_id(0);
  if (hole >= *hole_count) return;
  float3 sum = (float3)(0.0f, 0.0f, 0.0f);
  float4 albedo_sum = (float4)(0.0f, 0.0f, 0.0f, 0.0f);
  uint good = 0;
  int first_kind = -1;
  for (uint s = 0; s < spp; ++s) {
    const uint i = hole * spp + s;
    const float4 l = samples[2u * i];
    const float4 a = samples[2u * i + 1u];
    if (!(l.w > 0.0f)) continue; /* counted by path_trace_list_samples */
    if (!px_count_sample(&sum, &albedo_sum, &good, &first_kind, (int)same_kind_only, l.xyz, a)) atomic_inc(nonfinite);
  }
  const uint p = holes[hole];
  float4 albedo;
  out[p] = px_pixel_mean(sum, albedo_sum, good, &albedo);
  albedo_out[p] = albedo;
}

/* More samples for the pixels listed in `list` (*count of them; full-frame indices): the
 * pixels' samples fp.sample_offset .. fp.sample_offset + fp.spp - 1, joined to the mean already
 * in out / albedo_out, which stands for fp.sample_offset samples (the frame's spp; a pixel with
 * w = 0 had no finite one and counts none). The pixel becomes the mean of all of them, as a
 * render at the larger count would give it up to rounding: its first samples are the frame's,
 * the others continue the pixel's own stream. Used at moving objects' edges (motion_edges.cl). */
kernel void path_trace_list_more(global float4* out, global float4* albedo_out, volatile global uint* nonfinite,
                                 const global uint* list, const global uint* count, FrameParams fp, CameraParams cam,
                                 PX_SCENE_PARAMS) {
  const uint i = get_global_id(0);
  if (i >= *count) return;
  const SceneView scene = PX_SCENE_VIEW();
  const uint p = list[i];
  float4 albedo;
  const float4 more = px_render_pixel(&scene, &fp, &cam, p % cam.width, p / cam.width, nonfinite, &albedo, 0, 0);
  if (more.w <= 0.0f) return;
  const float4 had = out[p];
  const float n = had.w > 0.0f ? (float)fp.sample_offset : 0.0f;
  const float total = n + more.w;
  const float3 joined = (had.xyz * n + more.xyz * more.w) / total;
  if (!px_finite3(joined)) {
    atomic_inc(nonfinite);
    return;
  }
  out[p] = (float4)(joined, total);
  albedo_out[p] = (albedo_out[p] * n + albedo * more.w) / total;
}
