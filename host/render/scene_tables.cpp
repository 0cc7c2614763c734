// The scene's tables for the kernels: shading records, materials, lights (scene_tables.h).
#include "render/scene_tables.h"

#include "scene/punctual_light.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>
#include <stdexcept>

namespace px {

namespace {

void copy3(float* dst, const glm::vec3& v) {
  dst[0] = v.x;
  dst[1] = v.y;
  dst[2] = v.z;
}

float luminance(const glm::vec3& c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

constexpr float kPi = std::numbers::pi_v<float>;

}  // namespace

TriangleShading shading_of(const SceneTriangle& t) {
  TriangleShading s;
  copy3(s.n0, t.n[0]);
  copy3(s.n1, t.n[1]);
  copy3(s.n2, t.n[2]);
  s.uv0[0] = t.uv[0].x;
  s.uv0[1] = t.uv[0].y;
  s.uv1[0] = t.uv[1].x;
  s.uv1[1] = t.uv[1].y;
  s.uv2[0] = t.uv[2].x;
  s.uv2[1] = t.uv[2].y;
  s.material = t.material;
  return s;
}

FlatTriangleShading flat_shading_of(const SceneTriangle& t) {
  FlatTriangleShading s;
  copy3(s.n, t.n[0]);
  s.material = t.material;
  return s;
}

bool has_flat_shading(const std::vector<SceneTriangle>& triangles) {
  const auto same_bits = [](const void* a, const void* b, std::size_t n) { return std::memcmp(a, b, n) == 0; };
  const glm::vec2 zero(0.0f);
  for (const SceneTriangle& t : triangles) {
    if (!same_bits(&t.n[0], &t.n[1], sizeof t.n[0]) || !same_bits(&t.n[0], &t.n[2], sizeof t.n[0])) return false;
    for (const glm::vec2& uv : t.uv)
      if (!same_bits(&uv, &zero, sizeof uv)) return false;  // -0 too: the records would not say it
  }
  return true;
}

std::vector<TriangleShading> make_triangle_shading(const Scene& scene) {
  std::vector<TriangleShading> out(scene.triangles.size());
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = shading_of(scene.triangles[i]);
  return out;
}

std::vector<GpuMaterial> make_gpu_materials(const Scene& scene) {
  std::vector<GpuMaterial> out(scene.materials.size());
  for (std::size_t i = 0; i < out.size(); ++i) {
    const Material& m = scene.materials[i];
    GpuMaterial& g = out[i];
    g = GpuMaterial{};
    copy3(g.diffuse, m.diffuse);
    copy3(g.specular, m.specular);
    copy3(g.emission, m.emission);
    copy3(g.transmission, m.transmission);
    g.diffuse_texture = m.diffuse_texture;
    g.specular_texture = m.specular_texture;
    g.normal_texture = m.normal_texture;
    g.normal_scale = m.normal_scale;
    g.alpha_texture = m.alpha_texture;
    g.ior = m.ior;
    g.roughness = m.mirror ? 0.0f : m.roughness;
    const bool has_specular = (m.specular.x + m.specular.y + m.specular.z) > 0.0f;
    // A dielectric is its own lobe: it is neither mirror nor glossy, whatever Ks says.
    const bool opaque = !m.dielectric;
    g.flags = (opaque && m.mirror ? PX_MAT_MIRROR : 0u) | (opaque && !m.mirror && has_specular ? PX_MAT_GLOSSY : 0u) |
              (m.dielectric ? PX_MAT_DIELECTRIC : 0u) | (m.is_emissive() ? PX_MAT_EMISSIVE : 0u) |
              (m.two_sided ? PX_MAT_TWO_SIDED_EMITTER : 0u);
  }
  return out;
}

std::vector<LightTriangle> make_light_table(const Scene& scene) {
  std::vector<LightTriangle> out;
  double total = 0.0;
  std::vector<char> emissive(scene.materials.size());
  for (std::size_t k = 0; k < emissive.size(); ++k) emissive[k] = scene.materials[k].is_emissive();
  const bool any_emitter = std::find(emissive.begin(), emissive.end(), 1) != emissive.end();
  for (std::size_t i = 0; any_emitter && i < scene.triangles.size(); ++i) {
    const SceneTriangle& t = scene.triangles[i];
    if (!emissive.at(t.material)) continue;
    const Material& m = scene.materials[t.material];
    const float area = 0.5f * glm::length(glm::cross(t.p[1] - t.p[0], t.p[2] - t.p[0]));
    // Emitted power is pi * area * radiance per emitting face.
    const double power = static_cast<double>(area) * luminance(m.emission) * (m.two_sided ? 2.0 : 1.0);
    if (!(power > 0.0)) continue;
    LightTriangle l{};
    copy3(l.v0, t.p[0]);
    copy3(l.v1, t.p[1]);
    copy3(l.v2, t.p[2]);
    copy3(l.emission, m.emission);
    l.prim = static_cast<std::uint32_t>(i);
    l.area = area;
    l.pdf_select = static_cast<float>(power);  // normalised below
    total += power;
    out.push_back(l);
  }
  // Point and spot lights after the triangles (types.h, LightTriangle), power in the table's unit:
  // watts / pi, as a triangle's area x radiance.
  if (scene.punctual_lights.size() >= PX_LIGHT_PUNCTUAL)
    throw std::length_error("make_light_table: more point and spot lights than a prim can name");
  if (scene.triangles.size() > PX_LIGHT_PUNCTUAL)
    throw std::length_error("make_light_table: too many triangles to name point and spot lights after them");
  for (std::size_t k = 0; k < scene.punctual_lights.size(); ++k) {
    const PunctualLight& p = scene.punctual_lights[k];
    const double power = punctual_light_power(p);
    if (!(power > 0.0) || !std::isfinite(power)) continue;
    const SpotRamp ramp = spot_ramp(p);
    LightTriangle l{};
    copy3(l.v0, p.position);
    copy3(l.v1, p.direction);
    l.v2[0] = ramp.scale;
    l.v2[1] = ramp.offset;
    l.v2[2] = ramp.cos_outer;
    copy3(l.emission, p.intensity);
    l.prim = PX_LIGHT_PUNCTUAL + static_cast<std::uint32_t>(k);
    l.area = 0.0f;
    l.pdf_select = static_cast<float>(power);  // normalised below
    total += power;
    out.push_back(l);
  }
  double running = 0.0;
  for (auto& l : out) {
    running += l.pdf_select;
    l.pdf_select = static_cast<float>(l.pdf_select / total);
    l.cdf = static_cast<float>(running / total);
  }
  if (!out.empty()) out.back().cdf = 1.0f;  // exact end, whatever the rounding
  return out;
}

std::vector<std::uint32_t> material_triangle_flags(const Scene& scene) {
  std::vector<std::uint32_t> by_material(scene.materials.size());
  for (std::size_t k = 0; k < by_material.size(); ++k) {
    const Material& m = scene.materials[k];
    by_material[k] = (m.alpha_texture >= 0 ? PX_TRI_ALPHA_TESTED : 0u) | (m.is_emissive() ? PX_TRI_EMISSIVE : 0u);
  }
  return by_material;
}

std::uint32_t used_triangle_flags(const Scene& scene, const std::vector<std::uint32_t>& flags_per_material) {
  std::vector<char> used(flags_per_material.size(), 0);
  for (const SceneTriangle& t : scene.triangles) used.at(t.material) = 1;
  std::uint32_t flags = 0;
  for (std::size_t k = 0; k < used.size(); ++k)
    if (used[k]) flags |= flags_per_material[k];
  return flags;
}

std::vector<std::uint32_t> triangle_flags(const Scene& scene) {
  // By material first: a scene has few materials and may have 10M triangles.
  const std::vector<std::uint32_t> by_material = material_triangle_flags(scene);
  std::vector<std::uint32_t> out(scene.triangles.size());
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = by_material.at(scene.triangles[i].material);
  return out;
}

void fill_light_params(const Scene& scene, std::size_t light_count, FrameParams& p) {
  copy3(p.sun_dir, scene.sun.enabled ? glm::normalize(scene.sun.direction) : glm::vec3(0, 1, 0));
  p.sun_cos_max = std::cos(glm::radians(scene.sun.angular_radius_deg));
  copy3(p.sun_radiance, scene.sun.enabled ? scene.sun.radiance : glm::vec3(0.0f));
  copy3(p.sky_zenith, scene.sky.enabled ? scene.sky.zenith : glm::vec3(0.0f));
  copy3(p.sky_horizon, scene.sky.enabled ? scene.sky.horizon : glm::vec3(0.0f));
  copy3(p.sky_ground, scene.sky.enabled ? scene.sky.ground : glm::vec3(0.0f));
  p.light_count = static_cast<std::uint32_t>(light_count);
  // Each present kind of light gets an equal share of next-event samples: the kinds differ in
  // units (radiance of a disk, a dome, a set of triangles), so power is no fair common measure.
  const int kinds = (scene.sun.enabled ? 1 : 0) + (scene.sky.enabled ? 1 : 0) + (light_count > 0 ? 1 : 0);
  const float share = kinds > 0 ? 1.0f / static_cast<float>(kinds) : 0.0f;
  p.p_sun = scene.sun.enabled ? share : 0.0f;
  p.p_sky = scene.sky.enabled ? share : 0.0f;
  p.p_triangles = light_count > 0 ? share : 0.0f;
  // The sun and the sky are both at infinity, and so share a unit: the irradiance each gives a
  // surface facing it. Their two shares are split in that ratio, not evenly: atrium's sun gives
  // about 4x the sky's, and with half the samples each a sunlit pixel at 1 spp saw the sun in
  // one sample of two, at twice its weight, a binary noise that the denoiser's luminance test
  // partly took for edges (the sunlit floor came out darker, its shadows smeared). The sky
  // loses next-event samples in the shade, where BSDF sampling finds it well (MIS).
  if (scene.sun.enabled && scene.sky.enabled) {
    const float sun_solid_angle = 2.0f * kPi * (1.0f - p.sun_cos_max);
    const float e_sun = std::max(0.0f, luminance(scene.sun.radiance)) * sun_solid_angle;
    // A surface facing the zenith: 2 pi integral over mu = cos(theta) of
    // mix(horizon, zenith, sqrt(mu)) mu dmu = pi horizon + 4 pi (zenith - horizon) / 5.
    const float e_sky = std::max(
        0.0f, kPi * luminance(scene.sky.horizon) + 0.8f * kPi * luminance(scene.sky.zenith - scene.sky.horizon));
    if (e_sun + e_sky > 0.0f && std::isfinite(e_sun + e_sky)) {
      // Neither below a tenth of the pair's share: a dim sky still gets its next-event samples.
      const float sun_fraction = std::clamp(e_sun / (e_sun + e_sky), 0.1f, 0.9f);
      p.p_sun = 2.0f * share * sun_fraction;
      p.p_sky = 2.0f * share - p.p_sun;
    }
  }
}

}  // namespace px
