// Ray sets the benchmarks trace: a scene camera's primary rays and one diffuse bounce from their
// hits, the same for every tree or layout they compare.
#pragma once

#include "render/stereo_camera.h"
#include "scene/primitives.h"
#include "scene/scene.h"
#include "trace/ray_batch_tracer.h"

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace px::bench {

// The left eye's primary rays through pixel centres, in image order (coherent).
inline std::vector<px::Ray> primary_rays(const px::Scene& scene, unsigned w, unsigned h) {
  const auto cam = px::make_eye_camera(px::evaluate_camera(scene, 0.0f), px::Eye::Left, scene.ipd_units(), w, h);
  const glm::vec3 f(cam.forward[0], cam.forward[1], cam.forward[2]);
  const glm::vec3 r(cam.right[0], cam.right[1], cam.right[2]);
  const glm::vec3 u(cam.up[0], cam.up[1], cam.up[2]);
  std::vector<px::Ray> rays;
  rays.reserve(static_cast<std::size_t>(w) * h);
  for (unsigned y = 0; y < h; ++y)
    for (unsigned x = 0; x < w; ++x) {
      const float sx = ((x + 0.5f) / w * 2.0f - 1.0f) * cam.tan_half_fov_y * cam.aspect;
      const float sy = (1.0f - (y + 0.5f) / h * 2.0f) * cam.tan_half_fov_y;
      const glm::vec3 d = glm::normalize(f + sx * r + sy * u);
      px::Ray ray{};
      for (int i = 0; i < 3; ++i) {
        ray.org[i] = cam.origin[i];
        ray.dir[i] = d[i];
      }
      ray.tmin = 0.0f;
      ray.tmax = INFINITY;
      rays.push_back(ray);
    }
  return rays;
}

// Cosine-weighted directions around each primary hit's geometric normal (facing the viewer).
inline std::vector<px::Ray> bounce_rays(const px::Scene& scene, const std::vector<px::Ray>& primary,
                                        const std::vector<px::Hit>& hits, px::RayBatchTracer& tracer) {
  std::vector<glm::vec3> points, normals;
  for (std::size_t i = 0; i < hits.size(); ++i) {
    if (hits[i].prim == PX_NO_HIT) continue;
    const auto& t = scene.triangles[hits[i].prim];
    const float w = 1.0f - hits[i].u - hits[i].v;
    points.push_back(w * t.p[0] + hits[i].u * t.p[1] + hits[i].v * t.p[2]);
    glm::vec3 n = px::geometric_normal(t);
    if (glm::dot(n, glm::vec3(primary[i].dir[0], primary[i].dir[1], primary[i].dir[2])) > 0.0f) n = -n;
    normals.push_back(n);
  }
  auto origins = tracer.offset_origins(points, normals);
  std::mt19937 rng(1234);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  std::vector<px::Ray> rays;
  for (std::size_t i = 0; i < origins.size(); ++i) {
    const glm::vec3 n = normals[i];
    const glm::vec3 a = std::abs(n.x) > 0.9f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
    const glm::vec3 t = glm::normalize(glm::cross(a, n)), b = glm::cross(n, t);
    const float r = std::sqrt(u01(rng)), phi = 6.2831853f * u01(rng);
    const glm::vec3 d =
        glm::normalize(r * std::cos(phi) * t + r * std::sin(phi) * b + std::sqrt(std::max(0.0f, 1.0f - r * r)) * n);
    px::Ray ray{};
    for (int k = 0; k < 3; ++k) {
      ray.org[k] = origins[i][k];
      ray.dir[k] = d[k];
    }
    ray.tmin = 0.0f;
    ray.tmax = INFINITY;
    rays.push_back(ray);
  }
  return rays;
}

}  // namespace px::bench
