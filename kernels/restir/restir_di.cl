/* ReSTIR DI at the first hit of every traced pixel (the direct-light stage,
 * host/pipeline/stages/direct_light_stage.h). Two passes per eye and frame:
 *
 *   restir_candidates    traces the pixel's G-buffer ray (the ray of its sample 0, which the
 *                        path tracer left without next-event estimation at its first vertex),
 *                        draws RestirParams::candidates light samples from the scene's light
 *                        sampler and keeps one by resampling with the unshadowed contribution as
 *                        target; then reuses last frame's reservoir where the pixel's surface was;
 *   restir_spatial_shade reuses the reservoirs of a few neighbours, then shades the pixel with
 *                        the one sample kept: one shadow ray, its light added to the pixel's mean.
 *
 * Reuse is weighted by the generalized balance heuristic with confidence weights
 * (m_i(y) = M_i p_i(y) / sum_j M_j p_j(y), every p evaluated at its own pixel's surface in this
 * frame's scene), whose weights sum to one over the reservoirs taking part, so the estimate stays
 * unbiased while the reused samples come from other surfaces and last frame. Each pass's random
 * numbers are the pixel's own (sample streams keyed by pixel, frame and eye), and every surface
 * is rebuilt from its Hit record, so a pixel gets the same reservoir whichever device computes
 * it: the direct-light stage computes the candidates of the rows its neighbours' spatial taps
 * reach itself, and N devices give one device's image bit for bit. */
#include "shared/types.h"
#include "pathtrace/pixel_mean.h"
#include "render/camera.h"
#include "restir/reservoir.h"
#include "sampling/sample_stream.h"
#include "trace/traverse.h"

/* Sample streams of the two passes (the `sample` field of the key; paths use 0..spp-1). */
#define PX_RESTIR_CANDIDATE_STREAM 0x40000000u
#define PX_RESTIR_SPATIAL_STREAM 0x40000001u
/* Dimensions of the candidate stream: candidate c uses dimension c, its resampling coin dimension
 * PX_RESTIR_COIN_DIM + c / 4; the temporal merge's coins follow. */
#define PX_RESTIR_COIN_DIM 64u
#define PX_RESTIR_TEMPORAL_DIM 96u

/* The pixel of work-item i: the i-th of `list` (*list_count of them), or of rows rp.row0 ... */
inline int px_restir_pixel(uint i, const global uint* list, const global uint* list_count, const RestirParams* rp,
                           uint* pixel) {
  if (list) {
    if (i >= *list_count) return 0;
    *pixel = list[i];
    return 1;
  }
  if (i >= rp->rows * rp->width) return 0;
  *pixel = rp->row0 * rp->width + i;
  return 1;
}

/* Whether a reservoir of surface *b may be reused at surface *a: near the same plane and facing
 * the same way. Only the variance depends on this test; the weights keep the estimate unbiased
 * whichever reservoirs take part. */
inline int px_restir_similar(const ShadingPoint* a, const ShadingPoint* b) {
  if (!a->valid || !b->valid) return 0;
  if (dot(a->ns, b->ns) < PX_RESTIR_MIN_NORMAL_COS) return 0;
  return fabs(dot(a->ng, b->p - a->p)) <= PX_RESTIR_MAX_PLANE_DISTANCE * a->depth;
}

/* The pixel of camera *cam whose footprint point p falls in: 0 when p is behind the camera. */
inline int px_restir_project(const CameraParams* cam, float3 p, uint width, uint height, int* px, int* py) {
  const float3 d = p - px_camera_origin(cam);
  const float zf = dot(d, (float3)(cam->forward[0], cam->forward[1], cam->forward[2]));
  if (!(zf > 0.0f)) return 0;
  const float sx = dot(d, (float3)(cam->right[0], cam->right[1], cam->right[2])) / zf;
  const float sy = dot(d, (float3)(cam->up[0], cam->up[1], cam->up[2])) / zf;
  const float fx = (sx / (cam->tan_half_fov_y * cam->aspect) + 1.0f) * 0.5f * (float)width;
  const float fy = (1.0f - sy / cam->tan_half_fov_y) * 0.5f * (float)height;
  if (!(fx >= 0.0f && fx < (float)width && fy >= 0.0f && fy < (float)height)) return 0;
  *px = (int)fx;
  *py = (int)fy;
  return 1;
}

/* The coin for candidate k of a merge or a stream: component k % 4 of dimension dim + k / 4. */
inline float px_restir_coin(SampleKey key, uint dim, uint k) {
  const float4 u = px_sample4(key, dim + k / 4u);
  const uint c = k % 4u;
  return c == 0u ? u.x : c == 1u ? u.y : c == 2u ? u.z : u.w;
}

/* Merges the n reservoirs rs[0..n) of surfaces sps[0..n) into one for surface sps[0] (the pixel
 * being shaded): the generalized balance heuristic with confidence weights M. */
inline Reservoir px_restir_merge(const SceneView* s, const FrameParams* fp, const ShadingPoint* sps,
                                 const Reservoir* rs, uint n, SampleKey key, uint coin_dim, uint tag) {
  Reservoir out = px_empty_reservoir(tag);
  float wsum = 0.0f, chosen_target = 0.0f;
  for (uint i = 0; i < n; ++i) {
    out.M += rs[i].M;
    if (rs[i].light == PX_RESTIR_NO_LIGHT || !(rs[i].W > 0.0f)) continue;
    float target_here = 0.0f, own = 0.0f, all = 0.0f;
    for (uint j = 0; j < n; ++j) {
      const float t = px_restir_evaluate(s, fp, sps + j, rs[i].light, rs[i].y).target;
      if (j == 0u) target_here = t;
      if (j == i) own = rs[j].M * t;
      all += rs[j].M * t;
    }
    if (!(target_here > 0.0f) || !(all > 0.0f)) continue;
    const float w = own / all * target_here * rs[i].W;
    if (px_reservoir_offer(&out, &wsum, rs[i].light, rs[i].y, w, px_restir_coin(key, coin_dim, i)))
      chosen_target = target_here;
  }
  out.W = chosen_target > 0.0f && out.light != PX_RESTIR_NO_LIGHT ? wsum / chosen_target : 0.0f;
  if (!isfinite(out.W)) out.W = 0.0f;
  return out;
}

/* Pass 1 over rows [rp.row0, rp.row0 + rp.rows) (list null) or over the pixels in `list`:
 * traces each pixel's G-buffer ray (its hit to `hits`), resamples rp.candidates light samples,
 * then merges last frame's reservoir (prev_reservoirs, written with tag rp.prev_tag) of the pixel
 * the surface point fell in, found through `prev_cam`, if that pixel saw a similar surface
 * (prev_hits) and lies in rows [rp.lo_row, rp.hi_row) within rp.temporal_rows of the pixel's
 * row. Writes the pixel's reservoir (tag rp.tag) to `reservoirs`: what pass 2 reuses, and what next
 * frame's pass 1 reuses in turn (never pass 2's merge: feeding that back measured a bias of a few
 * percent that grows with the candidates and neighbours, docs/measurements.md, Many lights). */
kernel void restir_candidates(global float4* reservoirs, global uint4* hits, const global float4* prev_reservoirs,
                              const global uint4* prev_hits, const global uint* list, const global uint* list_count,
                              RestirParams rp, FrameParams fp, CameraParams cam, CameraParams prev_cam,
                              PX_SCENE_PARAMS) {
  uint pixel;
  if (!px_restir_pixel(get_global_id(0), list, list_count, &rp, &pixel)) return;
  const uint x = pixel % rp.width, y = pixel / rp.width;
  const SceneView scene = PX_SCENE_VIEW();
  const float3 eye = px_camera_origin(&cam);
  const Hit hit =
      px_trace_closest_leaf(&scene, eye, px_camera_dir(&cam, x, y, cam.jitter[0], cam.jitter[1]), 0.0f, INFINITY);
  hits[pixel] = px_pack_hit(hit);
  ShadingPoint sps[2];
  sps[0] = px_shading_point(&scene, hit, eye);
  Reservoir r = px_empty_reservoir(rp.tag);
  if (!sps[0].valid) {
    px_store_reservoir(reservoirs, pixel, r);
    return;
  }
  const SampleKey key = px_sample_key(x, y, fp.frame, fp.eye, PX_RESTIR_CANDIDATE_STREAM, fp.seed);
  const uint candidates = min(rp.candidates, (uint)PX_RESTIR_MAX_CANDIDATES);
  float wsum = 0.0f, chosen_target = 0.0f;
  for (uint c = 0; c < candidates; ++c) {
    uint light;
    float3 ly;
    const float pdf = px_restir_candidate(&scene, &fp, sps, px_sample4(key, c), &light, &ly);
    if (!(pdf > 0.0f)) continue;
    const float t = px_restir_evaluate(&scene, &fp, sps, light, ly).target;
    if (px_reservoir_offer(&r, &wsum, light, ly, t / pdf, px_restir_coin(key, PX_RESTIR_COIN_DIM, c)))
      chosen_target = t;
  }
  r.M = (float)candidates;
  r.W = chosen_target > 0.0f ? wsum / ((float)candidates * chosen_target) : 0.0f;
  if (!isfinite(r.W)) r.W = 0.0f;

  if (rp.temporal && prev_reservoirs) {
    const float3 prev_eye = px_camera_origin(&prev_cam);
    int px, py;
    if (px_restir_project(&prev_cam, sps[0].p, rp.width, rp.height, &px, &py)) {
      if (py >= (int)rp.lo_row && py < (int)rp.hi_row && abs(py - (int)y) <= (int)rp.temporal_rows) {
        const uint q = (uint)py * rp.width + (uint)px;
        Reservoir t = px_load_reservoir(prev_reservoirs, q);
        if (t.tag == rp.prev_tag && t.M > 0.0f) {
          sps[1] = px_shading_point(&scene, px_unpack_hit(prev_hits[q]), prev_eye);
          if (px_restir_similar(sps, sps + 1)) {
            /* Confidence capped: an old reservoir must not outweigh this frame's candidates for
             * ever (the cap bounds how long light that changed lingers). */
            t.M = fmin(t.M, rp.max_history * (float)candidates);
            Reservoir both[2];
            both[0] = r;
            both[1] = t;
            r = px_restir_merge(&scene, &fp, sps, both, 2u, key, PX_RESTIR_TEMPORAL_DIM, rp.tag);
          }
        }
      }
    }
  }
  px_store_reservoir(reservoirs, pixel, r);
}

/* Pass 2 over the same pixels: merges the pixel's reservoir with those of up to rp.neighbours
 * pixels within rp.radius in rows [rp.lo_row, rp.hi_row) that pass 1 wrote this frame (tag
 * rp.tag) and that see a similar surface, and, where `other_reservoirs` is given (the right eye's
 * holes: the left eye's kept reservoirs of this frame, seen by `other_cam`), with the other eye's
 * reservoir at the pixel where that eye sees the surface, in the same row (the eyes' strips hold
 * the same rows, so the row is always this device's), if it sees a similar surface there; and shades:
 * one shadow ray toward the sample kept; if it arrives, f Le cos G W over the pixel's sample
 * count is added to `radiance` (a non-finite value is counted in *nonfinite, never added). */
kernel void restir_spatial_shade(global float4* radiance, volatile global uint* nonfinite,
                                 const global float4* reservoirs, const global uint4* hits, const global uint* list,
                                 const global uint* list_count, const global float4* other_reservoirs,
                                 const global uint4* other_hits, RestirParams rp, FrameParams fp, CameraParams cam,
                                 CameraParams other_cam, PX_SCENE_PARAMS) {
  uint pixel;
  if (!px_restir_pixel(get_global_id(0), list, list_count, &rp, &pixel)) return;
  const int x = (int)(pixel % rp.width), y = (int)(pixel / rp.width);
  const SceneView scene = PX_SCENE_VIEW();
  const float3 eye = px_camera_origin(&cam);
  ShadingPoint sps[2 + PX_RESTIR_MAX_NEIGHBOURS];
  Reservoir rs[2 + PX_RESTIR_MAX_NEIGHBOURS];
  sps[0] = px_shading_point(&scene, px_unpack_hit(hits[pixel]), eye);
  if (!sps[0].valid) return;
  rs[0] = px_load_reservoir(reservoirs, pixel);
  const SampleKey key = px_sample_key((uint)x, (uint)y, fp.frame, fp.eye, PX_RESTIR_SPATIAL_STREAM, fp.seed);
  uint n = 1;
  const uint neighbours = min(rp.neighbours, (uint)PX_RESTIR_MAX_NEIGHBOURS);
  for (uint k = 0; k < neighbours; ++k) {
    const float4 u = px_sample4(key, k);
    const float radius = (float)rp.radius * sqrt(u.x);
    const float angle = 2.0f * PX_PI * u.y;
    const int nx = x + (int)round(radius * cos(angle)), ny = y + (int)round(radius * sin(angle));
    if ((nx == x && ny == y) || nx < 0 || nx >= (int)rp.width || ny < (int)rp.lo_row || ny >= (int)rp.hi_row) continue;
    const uint q = (uint)ny * rp.width + (uint)nx;
    const Reservoir nr = px_load_reservoir(reservoirs, q);
    if (nr.tag != rp.tag || !(nr.M > 0.0f)) continue;
    sps[n] = px_shading_point(&scene, px_unpack_hit(hits[q]), eye);
    if (!px_restir_similar(sps, sps + n)) continue;
    rs[n] = nr;
    ++n;
  }
  int ox, oy;
  if (other_reservoirs && px_restir_project(&other_cam, sps[0].p, rp.width, rp.height, &ox, &oy) && oy == y) {
    const uint q = (uint)oy * rp.width + (uint)ox;
    const Reservoir orr = px_load_reservoir(other_reservoirs, q);
    if (orr.tag == rp.tag && orr.M > 0.0f) {
      sps[n] = px_shading_point(&scene, px_unpack_hit(other_hits[q]), px_camera_origin(&other_cam));
      if (px_restir_similar(sps, sps + n)) {
        rs[n] = orr;
        ++n;
      }
    }
  }
  const Reservoir r = n > 1u ? px_restir_merge(&scene, &fp, sps, rs, n, key, PX_RESTIR_MAX_NEIGHBOURS, rp.tag) : rs[0];
  if (r.light == PX_RESTIR_NO_LIGHT || !(r.W > 0.0f)) return;
  const LightContribution c = px_restir_evaluate(&scene, &fp, sps, r.light, r.y);
  if (!(c.target > 0.0f)) return;
  /* Stop short of the light's own surface, as next-event estimation does. */
  const float tmax = isinf(c.dist) ? INFINITY : c.dist * (1.0f - 1e-4f);
  if (px_trace_any(&scene, sps[0].origin, c.wi, 0.0f, tmax)) return;
  const float3 direct = c.unshadowed * r.W;
  if (!px_finite3(direct)) {
    atomic_inc(nonfinite);
    return;
  }
  const float4 had = radiance[pixel];
  if (!(had.w > 0.0f)) return;
  const float3 sum = had.xyz + direct / had.w;
  if (!px_finite3(sum)) {
    atomic_inc(nonfinite);
    return;
  }
  radiance[pixel] = (float4)(sum, had.w);
}
