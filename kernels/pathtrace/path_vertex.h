/* One vertex of a camera path: what the path tracer does between two closest-hit queries.
 *
 * Both path tracers are built from it, so they compute the same paths to the last bit:
 *   - the megakernel (path_trace.cl: px_trace_path) loops over the vertices of one path in
 *     one work-item, tracing each shadow ray where it is made;
 *   - the wavefront tracer (wavefront.cl) runs one kernel per step over all paths (extend:
 *     closest hits; shade: px_path_vertex; connect: the shadow rays), keeping PathVertex in
 *     global memory between them (types.h: PX_PATH_STATE_FLOAT4S).
 * The shadow ray's contribution is computed here and added by the caller once the ray is known
 * to be unoccluded, in both tracers, so the additions to the radiance happen in the same order
 * and with the same roundings. */
#ifndef PARALLAX_PATH_VERTEX_H
#define PARALLAX_PATH_VERTEX_H

#include "shared/types.h"
#include "sampling/sample_stream.h"
#include "sampling/warp.h"
#include "scene/scene_view.h"
#include "shading/bsdf.h"
#include "shading/lights.h"
#include "shading/material.h"
#include "shading/normal_map.h"
#include "shading/surface_shading.h"
#include "trace/ray_offset.h"
#include "render/camera.h"

/* The state a path carries from one vertex to the next. */
typedef struct PathVertex {
  float3 org, dir; /* the next ray */
  float3 throughput;
  float3 radiance; /* gathered so far */
  float3 prev_n;   /* shading normal of the last vertex (the environment's MIS pdf) */
  float3 prev_p;   /* hit point of the last vertex (the light tree's MIS pmf, with prev_n) */
  float prev_pdf;  /* pdf of the last BSDF sample (MIS) */
  int prev_delta;  /* the last bounce was a delta one (the camera ray counts as one) */
  /* ReSTIR DI (restir/restir_di.cl) lights the first vertex of each pixel's G-buffer ray in its
   * own pass: PX_RESTIR_VERTEX_NEXT on such a camera ray (its vertex makes no next-event
   * estimate), PX_RESTIR_VERTEX_LAST after that vertex (emission its non-delta BSDF sample finds
   * is ReSTIR's already, and counts 0), else 0. */
  int restir;
  /* The demodulation albedo of the first vertex (px_demodulation_albedo; 1 where the ray
   * escapes or meets an emitter, whose radiance is its own "illumination") and, in w, 1 where
   * that vertex is a surface the denoiser filters, 0 where the ray escapes and -1 where it meets
   * an emitter (a pixel's sum counts both as 0: px_albedo_counted). */
  float4 primary_albedo;
} PathVertex;

/* A next-event-estimation ray and what it adds to the radiance if nothing blocks it. */
typedef struct ShadowRay {
  float3 org, dir, contribution;
  float tmax;
  int valid;
} ShadowRay;

/* Whether sample s of a launch (the pixel's sample fp->sample_offset + s) is the frame's first
 * with fp->gbuffer_ray_samples set: that sample is the G-buffer's own ray, through the camera's
 * jitter position of the frame (CameraParams::jitter), and writes the pixel's texel. */
inline int px_sample_on_gbuffer_ray(const FrameParams* fp, uint s) {
  return fp->gbuffer_ray_samples != PX_GBUFFER_RAY_NONE && fp->sample_offset + s == 0u;
}

/* Whether sample s's camera ray is the G-buffer's ray: the first sample's, or with
 * PX_GBUFFER_RAY_EVERY every sample's (which then start at the G-buffer's hit as well). */
inline int px_sample_along_gbuffer_ray(const FrameParams* fp, uint s) {
  return fp->gbuffer_ray_samples == PX_GBUFFER_RAY_EVERY || px_sample_on_gbuffer_ray(fp, s);
}

/* The camera ray's direction of sample s of pixel (x, y), whose stream is `key`: jittered over
 * the pixel by the stream's first two numbers, except the first sample on the G-buffer's ray.
 * That sample's first hit is the G-buffer's (gbuffer_texel.h), so the path tracer writes the
 * G-buffer of the pixels it traces instead of a second primary trace, and the radiance of that
 * sample belongs to the very surface the denoiser's G-buffer describes (lower error on every scene
 * measured: docs/measurements.md, "Sample 0 along the G-buffer's ray"). Its position in the
 * pixel moves from frame to frame (CameraParams::jitter), so over frames it covers the pixel
 * too. The pipeline's references keep every sample jittered: a reference integrates the whole
 * pixel in one frame. A denoised frame at several spp sends every sample along that ray
 * (PX_GBUFFER_RAY_EVERY): samples spread over the pixel mix surfaces the G-buffer does not
 * describe (a lamp's rim: lamp and ceiling under a ceiling texel), which the filter then spread
 * and darkened, so the denoised error rose with spp (docs/measurements.md, "Every sample along
 * the G-buffer's ray"); the jitter still covers the pixel over frames. */
inline float3 px_sample_camera_dir(const FrameParams* fp, const CameraParams* cam, SampleKey key, uint x, uint y,
                                   uint s) {
  if (px_sample_along_gbuffer_ray(fp, s)) return px_camera_dir(cam, x, y, cam->jitter[0], cam->jitter[1]);
  const float4 u = px_sample4(key, 0u);
  return px_camera_dir(cam, x, y, u.x, u.y);
}

#define PX_RESTIR_VERTEX_NEXT 1
#define PX_RESTIR_VERTEX_LAST 2

/* Whether sample s is a camera ray whose first vertex ReSTIR DI lights (PathVertex::restir). */
inline int px_restir_lights_first_vertex(const FrameParams* fp, uint s) {
  return fp->direct_light == PX_DIRECT_RESTIR && fp->light_sampling == PX_LIGHTS_MIS && px_sample_on_gbuffer_ray(fp, s);
}

/* A camera path from org along dir; `restir_first_vertex`: its first vertex's direct light is
 * ReSTIR's (px_restir_lights_first_vertex). */
inline PathVertex px_camera_path(float3 org, float3 dir, int restir_first_vertex) {
  PathVertex v;
  v.org = org;
  v.dir = dir;
  v.throughput = (float3)(1.0f, 1.0f, 1.0f);
  v.radiance = (float3)(0.0f, 0.0f, 0.0f);
  v.prev_n = (float3)(0.0f, 1.0f, 0.0f);
  v.prev_p = org;
  v.prev_pdf = 0.0f;
  v.prev_delta = 1;
  v.restir = restir_first_vertex ? PX_RESTIR_VERTEX_NEXT : 0;
  v.primary_albedo = (float4)(1.0f, 1.0f, 1.0f, 0.0f);
  return v;
}

/* Vertex `bounce` of path *v, whose ray (v->org, v->dir) found `hit`: adds what the vertex
 * emits (or the environment, for a miss), prepares the shadow ray of next-event estimation in
 * *shadow (valid = 0 if none), samples the BSDF for the next ray and applies Russian roulette.
 * Returns 1 if the path goes on from the updated *v, 0 if it ends here (the shadow ray, if
 * valid, still counts). */
inline int px_path_vertex(const SceneView* scene, const FrameParams* fp, SampleKey key, uint bounce, Hit hit,
                          PathVertex* v, ShadowRay* shadow) {
  shadow->valid = 0;
  const int use_nee = fp->light_sampling != PX_LIGHTS_BSDF;
  const int use_bsdf_light = fp->light_sampling != PX_LIGHTS_NEE;
  const float3 dir = v->dir;

  if (hit.prim == PX_NO_HIT) {
    const float3 le = px_environment(fp, dir);
    float w = 1.0f;
    if (!v->prev_delta) {
      if (!use_bsdf_light || v->restir == PX_RESTIR_VERTEX_LAST)
        w = 0.0f;
      else if (use_nee)
        w = px_mis_power(v->prev_pdf, px_environment_pdf(fp, v->prev_n, dir));
    }
    v->radiance += v->throughput * le * w;
    return 0;
  }

  const SurfaceHit surf = px_surface_hit(scene, hit);
  const uint prim = surf.prim;
  const global GpuMaterial* mat = surf.mat;
  const float3 p = surf.p;
  const float3 wo = -dir;
  float3 ng, ns;
  int outside;
  const int front_face = px_face_viewer(&surf, wo, &ng, &ns, &outside);

  if (bounce == 0u && (mat->flags & PX_MAT_EMISSIVE)) v->primary_albedo.w = -1.0f;
  int two_sided = PX_HAS(PX_FEATURE_TWO_SIDED) && (mat->flags & PX_MAT_TWO_SIDED_EMITTER);
  if (PX_HAS(PX_FEATURE_EMISSIVE) && (mat->flags & PX_MAT_EMISSIVE) && (front_face || two_sided)) {
    float w = 1.0f;
    if (!v->prev_delta) {
      if (!use_bsdf_light || v->restir == PX_RESTIR_VERTEX_LAST) {
        w = 0.0f;
      } else if (use_nee) {
        const int li = px_find_light(scene, fp->light_count, prim);
        /* The light's selection probability where NEE would have picked it: the last vertex. */
        const float lp = li >= 0 ? px_triangle_light_pdf(fp, scene->lights + li,
                                                         px_light_select_pmf(scene, fp, li, v->prev_p, v->prev_n),
                                                         hit.t, fabs(dot(ng, dir)))
                                 : 0.0f;
        w = px_mis_power(v->prev_pdf, lp);
      }
    }
    v->radiance += v->throughput * px_load3(mat->emission) * w;
  }
  if (bounce == fp->max_bounces) return 0;

  const Bsdf bsdf = px_surface_bsdf(scene, &surf, hit, wo, outside, &ns);
  if (bounce == 0u && !(mat->flags & PX_MAT_EMISSIVE))
    v->primary_albedo = (float4)(px_demodulation_albedo(&bsdf), 1.0f);
  const float3 origin = px_offset_ray_origin(p, ng);
  const float4 u_light = px_sample4(key, 1u + 2u * bounce);
  const float4 u_bsdf = px_sample4(key, 2u + 2u * bounce);

  /* Next-event estimation (only the non-delta part of the BSDF can use it). */
  const int has_smooth = bsdf.p_specular < 1.0f || !bsdf.mirror;
  if (use_nee && has_smooth && v->restir != PX_RESTIR_VERTEX_NEXT) {
    const LightSample ls = px_sample_light(scene, fp, p, ns, u_light);
    if (ls.pdf > 0.0f && dot(ng, ls.wi) > 0.0f && dot(ns, ls.wi) > 0.0f) {
      const float3 f = px_bsdf_eval(&bsdf, ns, wo, ls.wi);
      if (f.x + f.y + f.z > 0.0f) {
        /* A point or spot light is a delta: BSDF sampling never finds it, NEE alone counts. */
        float w = use_bsdf_light ? px_mis_power(ls.pdf, px_bsdf_pdf(&bsdf, ns, wo, ls.wi)) : 1.0f;
        if (PX_HAS(PX_FEATURE_PUNCTUAL) && ls.delta) w = 1.0f;
        shadow->valid = 1;
        shadow->org = origin;
        shadow->dir = ls.wi;
        /* Stop short of the light's own surface; environment rays are unbounded. */
        shadow->tmax = isinf(ls.dist) ? INFINITY : ls.dist * (1.0f - 1e-4f);
        shadow->contribution = v->throughput * f * ls.radiance * (dot(ns, ls.wi) * w / ls.pdf);
      }
    }
  }

  const BsdfSample bs = px_bsdf_sample(&bsdf, ns, wo, u_bsdf.xyz);
  /* A refracted direction must cross the surface; any other must stay on the viewer's side. */
  const float side = bs.transmitted ? -1.0f : 1.0f;
  if (!bs.valid || side * dot(ng, bs.wi) <= 0.0f) return 0;
  v->throughput *= bs.weight;
  v->prev_pdf = bs.pdf;
  v->prev_delta = bs.delta;
  v->restir = v->restir == PX_RESTIR_VERTEX_NEXT ? PX_RESTIR_VERTEX_LAST : 0;
  v->prev_n = ns;
  v->prev_p = p;

  if (bounce + 1u >= fp->rr_start_bounce) {
    const float q = fmin(0.95f, fmax(v->throughput.x, fmax(v->throughput.y, v->throughput.z)));
    if (!(u_bsdf.w < q)) return 0;
    v->throughput /= q;
  }
  v->org = bs.transmitted ? px_offset_ray_origin(p, -ng) : origin;
  v->dir = bs.wi;
  return 1;
}

#endif
