/* Wavefront path tracing: the megakernel's paths (path_trace.cl), computed one step at a time
 * over all paths of a launch, a kernel per step (Laine, Karras, Aila 2013, "Megakernels
 * considered harmful"):
 *
 *   wf_generate_rows / wf_generate_list   a camera ray per (pixel, sample) pair
 *   then for each vertex b = 0..max_bounces, over the paths still alive:
 *     wf_extend    closest hits
 *     wf_shade     px_path_vertex: emission, next-event ray, BSDF sample, Russian roulette;
 *                  the paths that go on are appended to the next vertex's queue (a prefix
 *                  sum per work-group, parallel/group_scan.h: one atomic per group and queue)
 *     wf_connect   the shadow rays; unblocked ones add their contribution
 *   wf_resolve    each pixel's mean over its samples, as px_render_pixel takes it
 *
 * Each kernel does less, so it needs fewer registers than the megakernel and its work-items
 * diverge less (a work-group traces rays, or shades, but not both); the queues drop the paths
 * that ended. The price is the path state's round trip through memory at every vertex. Every
 * sample is the megakernel's to the last bit: the same vertex code (path_vertex.h), the same
 * additions in the same order, the same per-pixel sum (buffers: types.h, PX_PATH_STATE_FLOAT4S).
 * Launches are sized for the worst case (every path alive); items past a queue's count return. */
#include "shared/types.h"
#include "pathtrace/path_vertex.h"
#include "pathtrace/pixel_mean.h"
#include "parallel/group_scan.h"
#include "pipeline/gbuffer_texel.h"
#include "render/camera.h"
#include "trace/traverse.h"

inline void px_store_path(global float4* states, uint i, const PathVertex* v) {
  global float4* s = states + (size_t)i * PX_PATH_STATE_FLOAT4S;
  s[0] = (float4)(v->org, v->prev_pdf);
  /* w: prev_delta (0/1) + 2 x restir (PathVertex::restir, 0..2). */
  s[1] = (float4)(v->dir, (float)((v->prev_delta ? 1 : 0) + 2 * v->restir));
  s[2] = (float4)(v->throughput, v->prev_p.x);
  s[3] = (float4)(v->radiance, v->prev_p.y);
  s[4] = (float4)(v->prev_n, v->prev_p.z);
  s[5] = v->primary_albedo;
}

inline PathVertex px_load_path(const global float4* states, uint i) {
  const global float4* s = states + (size_t)i * PX_PATH_STATE_FLOAT4S;
  PathVertex v;
  const float4 o = s[0], d = s[1];
  v.org = o.xyz;
  v.prev_pdf = o.w;
  v.dir = d.xyz;
  const int bits = (int)d.w;
  v.prev_delta = bits & 1;
  v.restir = bits >> 1;
  const float4 t = s[2], r = s[3], n = s[4];
  v.throughput = t.xyz;
  v.radiance = r.xyz;
  v.prev_n = n.xyz;
  v.prev_p = (float3)(t.w, r.w, n.w);
  v.primary_albedo = s[5];
  return v;
}

/* The sample stream of path i, which traces sample i % spp of full-frame pixel `pixel`. */
inline SampleKey px_path_key(const FrameParams* fp, uint width, uint pixel, uint i) {
  return px_sample_key(pixel % width, pixel / width, fp->frame, fp->eye, fp->sample_offset + i % fp->spp, fp->seed);
}

/* Path i's camera ray (px_render_sample's) from pixel `pixel`, queued for vertex 0. */
inline void px_generate(global float4* states, global uint* path_pixel, global uint* queue, const FrameParams* fp,
                        const CameraParams* cam, uint pixel, uint i) {
  const SampleKey key = px_path_key(fp, cam->width, pixel, i);
  const float3 dir = px_sample_camera_dir(fp, cam, key, pixel % cam->width, pixel / cam->width, i % fp->spp);
  const PathVertex v = px_camera_path(px_camera_origin(cam), dir, px_restir_lights_first_vertex(fp, i % fp->spp));
  px_store_path(states, i, &v);
  path_pixel[i] = pixel;
  queue[i] = i;
}

/* A generate kernel's start: work-item 0 sets the launch's counts (`slots` pixels, fp->spp paths
 * each, all alive at vertex 0). Returns whether work-item i has a path to generate. */
inline int px_generate_counts(global uint* counts, uint slots, const FrameParams* fp, uint i) {
  if (i == 0u) {
    counts[0] = slots;
    counts[PX_WF_LIVE] = slots * fp->spp;
  }
  return i < slots * fp->spp;
}

/* Every pixel of rows [fp.row0, fp.row0 + fp.rows), fp.spp paths each. */
kernel void wf_generate_rows(global float4* states, global uint* path_pixel, global uint* queue, global uint* counts,
                             FrameParams fp, CameraParams cam) {
  const uint i = get_global_id(0);
  if (!px_generate_counts(counts, fp.rows * cam.width, &fp, i)) return;
  px_generate(states, path_pixel, queue, &fp, &cam, fp.row0 * cam.width + i / fp.spp, i);
}

/* The *hole_count pixels listed in `holes` (stage 5), fp.spp paths each. */
kernel void wf_generate_list(global float4* states, global uint* path_pixel, global uint* queue, global uint* counts,
                             const global uint* holes, const global uint* hole_count, FrameParams fp,
                             CameraParams cam) {
  const uint i = get_global_id(0);
  if (!px_generate_counts(counts, *hole_count, &fp, i)) return;
  px_generate(states, path_pixel, queue, &fp, &cam, holes[i / fp.spp], i);
}

/* The live paths' closest hits at vertex `bounce`. `gbuffer_hits`: null, or the G-buffer pass's
 * full-frame hits, which the camera rays along the G-buffer's rays (px_sample_along_gbuffer_ray) take
 * instead of a trace (as px_trace_path does). */
kernel void wf_extend(const global float4* states, global Hit* hits, const global uint* queue,
                      const global uint* counts, uint bounce, const global uint* path_pixel,
                      const global Hit* gbuffer_hits, FrameParams fp, PX_SCENE_PARAMS) {
  const uint j = get_global_id(0);
  if (j >= counts[PX_WF_LIVE + bounce]) return;
  const uint i = queue[j];
  if (bounce == 0u && gbuffer_hits && px_sample_along_gbuffer_ray(&fp, i % fp.spp)) {
    hits[i] = gbuffer_hits[path_pixel[i]];
    return;
  }
  const SceneView scene = PX_SCENE_VIEW();
  const global float4* s = states + (size_t)i * PX_PATH_STATE_FLOAT4S;
  hits[i] = px_trace_closest_leaf(&scene, s[0].xyz, s[1].xyz, 0.0f, INFINITY);
}

/* The live paths' vertex `bounce`. At vertex 0, the first sample (the G-buffer's ray)'s path writes its
 * pixel's texel of `gbuffer` (if not null), as the megakernel does. Each work-group appends its paths that go on to the
 * next vertex's queue, and its shadow rays to the shadow queue, with one prefix sum for both (live paths in the low 16
 * bits, shadow rays in the high: at most PX_LOCAL_SIZE each) and one atomic_add per queue: a queue keeps its paths in
 * the order of the queue before, group by group, so neighbouring work-items keep tracing neighbouring pixels' paths. */
#if PX_LOCAL_SIZE > 0xffff
#error "wf_shade packs two per-group counts of at most PX_LOCAL_SIZE into 16 bits each"
#endif
__attribute__((reqd_work_group_size(PX_LOCAL_SIZE, 1, 1))) kernel void wf_shade(
    global float4* states, global float4* shadows, const global Hit* hits, const global uint* path_pixel,
    const global uint* queue, global uint* next_queue, global uint* shadow_queue, volatile global uint* counts,
    uint bounce, global GBufferTexel* gbuffer, FrameParams fp, CameraParams cam, PX_SCENE_PARAMS) {
  local uint scan[PX_LOCAL_SIZE];
  local uint bases[2];
  const uint j = get_global_id(0), lid = get_local_id(0);
  /* No early return: every work-item of the group takes part in the prefix sum below. */
  uint i = 0u;
  int goes_on = 0, has_shadow = 0;
  if (j < counts[PX_WF_LIVE + bounce]) {
    const SceneView scene = PX_SCENE_VIEW();
    i = queue[j];
    PathVertex v = px_load_path(states, i);
    const Hit hit = hits[i];
    if (bounce == 0u && gbuffer && px_sample_on_gbuffer_ray(&fp, i % fp.spp))
      gbuffer[path_pixel[i]] = px_gbuffer_texel(&scene, v.dir, hit);
    ShadowRay shadow;
    goes_on = px_path_vertex(&scene, &fp, px_path_key(&fp, cam.width, path_pixel[i], i), bounce, hit, &v, &shadow);
    px_store_path(states, i, &v);
    if (shadow.valid) {
      global float4* r = shadows + (size_t)i * PX_SHADOW_RAY_FLOAT4S;
      r[0] = (float4)(shadow.org, shadow.tmax);
      r[1] = (float4)(shadow.dir, 0.0f);
      r[2] = (float4)(shadow.contribution, 0.0f);
      has_shadow = 1;
    }
  }
  const uint mine = px_group_inclusive_scan((goes_on ? 1u : 0u) | (has_shadow ? 0x10000u : 0u), scan);
  if (lid == PX_LOCAL_SIZE - 1u) {
    const uint live = mine & 0xffffu, made = mine >> 16;
    /* px_path_vertex ends every path at vertex max_bounces, so the next queue stays in range. */
    bases[0] = live ? atomic_add(counts + PX_WF_LIVE + bounce + 1u, live) : 0u;
    bases[1] = made ? atomic_add(counts + PX_WF_SHADOWS + bounce, made) : 0u;
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  if (goes_on) next_queue[bases[0] + (mine & 0xffffu) - 1u] = i;
  if (has_shadow) shadow_queue[bases[1] + (mine >> 16) - 1u] = i;
}

kernel void wf_connect(global float4* states, const global float4* shadows, const global uint* shadow_queue,
                       const global uint* counts, uint bounce, PX_SCENE_PARAMS) {
  const uint j = get_global_id(0);
  if (j >= counts[PX_WF_SHADOWS + bounce]) return;
  const SceneView scene = PX_SCENE_VIEW();
  const uint i = shadow_queue[j];
  const global float4* r = shadows + (size_t)i * PX_SHADOW_RAY_FLOAT4S;
  const float4 o = r[0];
  if (px_trace_any(&scene, o.xyz, r[1].xyz, 0.0f, o.w)) return;
  global float4* radiance = states + (size_t)i * PX_PATH_STATE_FLOAT4S + 3;
  float4 l = *radiance; /* w: prev_p.y, kept */
  l.xyz += r[2].xyz;
  *radiance = l;
}

/* Slot k's pixel: its fp.spp samples summed in sample order (dropping and counting non-finite
 * ones), then px_pixel_mean, as px_render_pixel does. A pixel's samples may come in several
 * launches (batches of samples, so that the paths fit in memory): `acc` (two float4 per slot:
 * the radiance sum with the finite-sample count in w, then the albedo sum) carries the sums from
 * one to the next, in the same order; `first` starts them, `last` writes the pixel. */
kernel void wf_resolve(global float4* out, global float4* albedo_out, volatile global uint* nonfinite,
                       const global float4* states, const global uint* path_pixel, const global uint* counts,
                       global float4* acc, uint spp, uint first, uint last, uint same_kind_only) {
  const uint k = get_global_id(0);
  if (k >= counts[0]) return;
  float3 sum = (float3)(0.0f, 0.0f, 0.0f);
  float4 albedo_sum = (float4)(0.0f, 0.0f, 0.0f, 0.0f);
  uint good = 0;
  int first_kind = -1;
  if (!first) {
    /* The batches before: the sum and count, the count negative where the first counted sample
     * was an emitter's (its kind, px_sample_kind). */
    const float4 a = acc[2u * k];
    sum = a.xyz;
    good = (uint)fabs(a.w);
    first_kind = good > 0u ? (a.w < 0.0f ? 1 : 0) : -1;
    albedo_sum = acc[2u * k + 1u];
  }
  for (uint s = 0; s < spp; ++s) {
    const global float4* st = states + (size_t)(k * spp + s) * PX_PATH_STATE_FLOAT4S;
    const float3 l = st[3].xyz;
    const float4 a = st[5];
    if (!px_count_sample(&sum, &albedo_sum, &good, &first_kind, (int)same_kind_only, l, a)) atomic_inc(nonfinite);
  }
  if (!last) {
    acc[2u * k] = (float4)(sum, first_kind == 1 ? -(float)good : (float)good);
    acc[2u * k + 1u] = albedo_sum;
    return;
  }
  const uint p = path_pixel[k * spp];
  float4 albedo;
  out[p] = px_pixel_mean(sum, albedo_sum, good, &albedo);
  albedo_out[p] = albedo;
}
