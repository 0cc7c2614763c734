/* Path tracing megakernel: one work-item per pixel of a strip of rows of one eye, `spp`
 * paths each, next-event estimation and BSDF sampling combined by the power heuristic,
 * Russian roulette from `rr_start_bounce`, at most `max_bounces` bounces.
 *
 * Every random number comes from the counter-based stream keyed by (frame, eye, pixel,
 * sample, dimension), so the result is independent of which device or strip ran the pixel.
 * A path whose radiance is not finite is dropped (left out of the pixel's mean) and counted
 * in `nonfinite`: no NaN or Inf ever reaches the output. */
#include "shared/types.h"
#include "render/camera.h"
#include "sampling/sample_stream.h"
#include "sampling/warp.h"
#include "scene/scene_view.h"
#include "shading/bsdf.h"
#include "shading/lights.h"
#include "shading/material.h"
#include "shading/normal_map.h"
#include "trace/ray_offset.h"
#include "trace/traverse.h"

/* Radiance along one camera path. *primary_albedo receives the demodulation albedo of the
 * first vertex (px_demodulation_albedo; 1 where the ray escapes or meets an emitter, whose
 * radiance is its own "illumination") and, in w, 1 where that vertex is a surface the denoiser
 * filters (not an emitter, not the environment), else 0. */
inline float3 px_trace_path(const SceneView* scene, const FrameParams* fp, float3 org, float3 dir,
                            SampleKey key, float4* primary_albedo) {
  *primary_albedo = (float4)(1.0f, 1.0f, 1.0f, 0.0f);
  float3 radiance = (float3)(0.0f, 0.0f, 0.0f);
  float3 throughput = (float3)(1.0f, 1.0f, 1.0f);
  float prev_pdf = 0.0f;
  int prev_delta = 1; /* the camera ray counts as a delta "bounce": emission seen directly is kept */
  float3 prev_n = (float3)(0.0f, 1.0f, 0.0f);
  const int use_nee = fp->light_sampling != PX_LIGHTS_BSDF;
  const int use_bsdf_light = fp->light_sampling != PX_LIGHTS_NEE;

  for (uint bounce = 0; bounce <= fp->max_bounces; ++bounce) {
    const Hit hit = px_trace_closest_leaf(scene, org, dir, 0.0f, INFINITY);
    if (hit.prim == PX_NO_HIT) {
      const float3 le = px_environment(fp, dir);
      float w = 1.0f;
      if (!prev_delta) {
        if (!use_bsdf_light) w = 0.0f;
        else if (use_nee) w = px_mis_power(prev_pdf, px_environment_pdf(fp, prev_n, dir));
      }
      radiance += throughput * le * w;
      break;
    }

    const global BvhTriangle* tri = scene->tris + hit.prim;
    const uint prim = tri->prim;
    const global TriangleShading* sh = scene->shading + prim;
    const global GpuMaterial* mat = scene->materials + sh->material;
    const float3 v0 = px_load3(tri->v0), v1 = px_load3(tri->v1), v2 = px_load3(tri->v2);
    const float bw = 1.0f - hit.u - hit.v;
    const float3 p = bw * v0 + hit.u * v1 + hit.v * v2;
    const float3 wo = -dir;
    float3 ng = normalize(cross(v1 - v0, v2 - v0));
    float3 ns = bw * px_load3(sh->n0) + hit.u * px_load3(sh->n1) + hit.v * px_load3(sh->n2);
    const float ns_len = length(ns);
    ns = ns_len > 0.0f && isfinite(ns_len) ? ns / ns_len : ng;
    /* The winding order's normal is the front; emitters light only that side (unless two-sided). */
    const int front_face = dot(ng, wo) > 0.0f;
    /* The side the path arrives from, for glass: the geometric normal oriented like the vertex
     * normals (outwards on closed meshes), taken before the two-sided flips below. */
    const int outside = front_face == (dot(ng, ns) >= 0.0f);
    /* Two-sided surfaces: face both normals towards the viewer of this vertex. */
    if (!front_face) ng = -ng;
    if (dot(ns, ng) < 0.0f) ns = -ns;

    if ((mat->flags & PX_MAT_EMISSIVE) && (front_face || (mat->flags & PX_MAT_TWO_SIDED_EMITTER))) {
      float w = 1.0f;
      if (!prev_delta) {
        if (!use_bsdf_light) {
          w = 0.0f;
        } else if (use_nee) {
          const int li = px_find_light(scene, fp->light_count, prim);
          const float lp = li >= 0 ? px_triangle_light_pdf(fp, scene->lights + li, hit.t, fabs(dot(ng, dir))) : 0.0f;
          w = px_mis_power(prev_pdf, lp);
        }
      }
      radiance += throughput * px_load3(mat->emission) * w;
    }
    if (bounce == fp->max_bounces) break;

    float3 albedo = px_load3(mat->diffuse);
    if (mat->diffuse_texture >= 0)
      albedo *= px_texture_bilinear(scene, mat->diffuse_texture, px_interpolate_uv(sh, hit.u, hit.v)).xyz;
    const float2 uv = px_interpolate_uv(sh, hit.u, hit.v);
    if (mat->normal_texture >= 0) ns = px_normal_mapped(scene, mat, sh, v0, v1, v2, uv, ns, wo);
    const Bsdf bsdf = px_material_bsdf(scene, mat, albedo, uv, outside);
    if (bounce == 0u && !(mat->flags & PX_MAT_EMISSIVE)) *primary_albedo = (float4)(px_demodulation_albedo(&bsdf), 1.0f);
    const float3 origin = px_offset_ray_origin(p, ng);
    const float4 u_light = px_sample4(key, 1u + 2u * bounce);
    const float4 u_bsdf = px_sample4(key, 2u + 2u * bounce);

    /* Next-event estimation (only the non-delta part of the BSDF can use it). */
    const int has_smooth = bsdf.p_specular < 1.0f || !bsdf.mirror;
    if (use_nee && has_smooth) {
      const LightSample ls = px_sample_light(scene, fp, p, ns, u_light);
      if (ls.pdf > 0.0f && dot(ng, ls.wi) > 0.0f && dot(ns, ls.wi) > 0.0f) {
        const float3 f = px_bsdf_eval(&bsdf, ns, wo, ls.wi);
        if (f.x + f.y + f.z > 0.0f) {
          /* Stop short of the light's own surface; environment rays are unbounded. */
          const float tmax = isinf(ls.dist) ? INFINITY : ls.dist * (1.0f - 1e-4f);
          if (!px_trace_any(scene, origin, ls.wi, 0.0f, tmax)) {
            const float w = use_bsdf_light ? px_mis_power(ls.pdf, px_bsdf_pdf(&bsdf, ns, wo, ls.wi)) : 1.0f;
            radiance += throughput * f * ls.radiance * (dot(ns, ls.wi) * w / ls.pdf);
          }
        }
      }
    }

    const BsdfSample bs = px_bsdf_sample(&bsdf, ns, wo, u_bsdf.xyz);
    /* A refracted direction must cross the surface; any other must stay on the viewer's side. */
    const float side = bs.transmitted ? -1.0f : 1.0f;
    if (!bs.valid || side * dot(ng, bs.wi) <= 0.0f) break;
    throughput *= bs.weight;
    prev_pdf = bs.pdf;
    prev_delta = bs.delta;
    prev_n = ns;

    if (bounce + 1u >= fp->rr_start_bounce) {
      const float q = fmin(0.95f, fmax(throughput.x, fmax(throughput.y, throughput.z)));
      if (!(u_bsdf.w < q)) break;
      throughput /= q;
    }
    org = bs.transmitted ? px_offset_ray_origin(p, -ng) : origin;
    dir = bs.wi;
  }
  return radiance;
}

/* Sample s of pixel (x, y): the radiance of its camera path, and in *albedo the path's primary
 * demodulation albedo (see px_trace_path). Every random number comes from the pixel's and the
 * sample's own stream, so a sample is the same whichever work-item traces it. */
inline float3 px_render_sample(const SceneView* scene, const FrameParams* fp, const CameraParams* cam, uint x, uint y,
                               uint s, float4* albedo) {
  const SampleKey key = px_sample_key(x, y, fp->frame, fp->eye, fp->sample_offset + s, fp->seed);
  const float4 u = px_sample4(key, 0u);
  const float3 dir = px_camera_dir(cam, x, y, u.x, u.y);
  return px_trace_path(scene, fp, px_camera_origin(cam), dir, key, albedo);
}

inline int px_finite3(float3 v) { return isfinite(v.x) && isfinite(v.y) && isfinite(v.z); }

/* A pixel's mean from the sum of its `good` finite samples: (rgb, good), and in *albedo the mean
 * albedo (w: the coverage). No finite path: (1, 1, 1, 0). */
inline float4 px_pixel_mean(float3 sum, float4 albedo_sum, uint good, float4* albedo) {
  const float inv = good > 0u ? 1.0f / (float)good : 0.0f;
  *albedo = good > 0u ? albedo_sum * inv : (float4)(1.0f, 1.0f, 1.0f, 0.0f);
  return (float4)(good > 0u ? sum / (float)good : sum, (float)good);
}

/* Mean radiance of pixel (x, y): fp->spp paths; a path with non-finite radiance is dropped
 * from the mean and counted in *nonfinite. Returns (rgb, finite sample count); *albedo gets
 * the mean primary demodulation albedo of the same (finite) paths, so that radiance / albedo
 * is the pixel's illumination even where the albedo varies inside the pixel (textures,
 * silhouettes, cut-outs); its w is the fraction of those paths whose camera ray met a surface
 * the denoiser filters (the pixel's coverage: SVGF filters a silhouette pixel whose centre
 * misses the object but whose samples hit it). No finite path: (1, 1, 1, 0). */
inline float4 px_render_pixel(const SceneView* scene, const FrameParams* fp, const CameraParams* cam,
                              uint x, uint y, volatile global uint* nonfinite, float4* albedo) {
  float3 sum = (float3)(0.0f, 0.0f, 0.0f);
  float4 albedo_sum = (float4)(0.0f, 0.0f, 0.0f, 0.0f);
  uint good = 0;
  for (uint s = 0; s < fp->spp; ++s) {
    float4 a;
    const float3 l = px_render_sample(scene, fp, cam, x, y, s, &a);
    if (px_finite3(l)) {
      sum += l;
      albedo_sum += a;
      ++good;
    } else {
      atomic_inc(nonfinite);
    }
  }
  return px_pixel_mean(sum, albedo_sum, good, albedo);
}

/* Stage 2 (and mono): every pixel of rows [fp.row0, fp.row0 + fp.rows) of eye fp.eye.
 * out, albedo_out: full-frame float4 images (width * height); only these rows are written. */
kernel void path_trace(global float4* out, global float4* albedo_out, volatile global uint* nonfinite,
                       FrameParams fp, CameraParams cam, PX_SCENE_PARAMS) {
  const uint i = get_global_id(0);
  if (i >= fp.rows * cam.width) return;
  const SceneView scene = PX_SCENE_VIEW();
  const uint p = fp.row0 * cam.width + i;
  float4 albedo;
  out[p] = px_render_pixel(&scene, &fp, &cam, p % cam.width, p / cam.width, nonfinite, &albedo);
  albedo_out[p] = albedo;
}

/* Stage 5, hole filling: only the pixels listed in `holes` (full-frame indices, *hole_count of
 * them, compacted by compact_holes), so work-items do not idle on reprojected pixels. The launch
 * is sized for the worst case; items past the count return at once. */
kernel void path_trace_list(global float4* out, global float4* albedo_out, volatile global uint* nonfinite,
                            const global uint* holes, const global uint* hole_count, FrameParams fp,
                            CameraParams cam, PX_SCENE_PARAMS) {
  const uint i = get_global_id(0);
  if (i >= *hole_count) return;
  const SceneView scene = PX_SCENE_VIEW();
  const uint p = holes[i];
  float4 albedo;
  out[p] = px_render_pixel(&scene, &fp, &cam, p % cam.width, p / cam.width, nonfinite, &albedo);
  albedo_out[p] = albedo;
}

/* Stage 5 with the samples spread: one work-item per (hole, sample) pair, so that a launch at
 * spp samples has spp times as many items as holes. At 1280x720 a frame's ~60k holes are too
 * few work-items to fill a large GPU; at 4 spp this gives it 240k. Each item writes its sample
 * (radiance with w = 1 if finite, else all 0; then its albedo) to `samples`, two float4 per
 * pair; resolve_hole_samples averages them. Images are bit-identical to path_trace_list: the
 * same samples, summed in the same order. */
kernel void path_trace_list_samples(global float4* samples, volatile global uint* nonfinite, const global uint* holes,
                                    const global uint* hole_count, FrameParams fp, CameraParams cam,
                                    PX_SCENE_PARAMS) {
  const uint i = get_global_id(0);
  const uint hole = i / fp.spp, s = i % fp.spp;
  if (hole >= *hole_count) return;
  const SceneView scene = PX_SCENE_VIEW();
  const uint p = holes[hole];
  float4 a;
  const float3 l = px_render_sample(&scene, &fp, &cam, p % cam.width, p / cam.width, s, &a);
  const int finite = px_finite3(l);
  if (!finite) atomic_inc(nonfinite);
  samples[2u * i] = finite ? (float4)(l, 1.0f) : (float4)(0.0f, 0.0f, 0.0f, 0.0f);
  samples[2u * i + 1u] = a;
}

/* The pixels of path_trace_list_samples: per hole, its spp samples summed in sample order (as
 * px_render_pixel sums them), then the same mean. */
kernel void resolve_hole_samples(global float4* out, global float4* albedo_out, const global float4* samples,
                                 const global uint* holes, const global uint* hole_count, uint spp) {
  const uint hole = get_global_id(0);
  if (hole >= *hole_count) return;
  float3 sum = (float3)(0.0f, 0.0f, 0.0f);
  float4 albedo_sum = (float4)(0.0f, 0.0f, 0.0f, 0.0f);
  uint good = 0;
  for (uint s = 0; s < spp; ++s) {
    const uint i = hole * spp + s;
    const float4 l = samples[2u * i];
    if (l.w > 0.0f) {
      sum += l.xyz;
      albedo_sum += samples[2u * i + 1u];
      ++good;
    }
  }
  const uint p = holes[hole];
  float4 albedo;
  out[p] = px_pixel_mean(sum, albedo_sum, good, &albedo);
  albedo_out[p] = albedo;
}
