#include "render/kernel_features.h"

#include <algorithm>

namespace px {

static_assert(PX_FEATURES_ALL == (1u << 13) - 1u, "kernel_feature_names() lists one name per PX_FEATURE_* bit");

namespace {

bool any_positive(const float (&c)[3]) { return c[0] > 0.0f || c[1] > 0.0f || c[2] > 0.0f; }
bool any_nonzero(const float (&c)[3]) { return c[0] != 0.0f || c[1] != 0.0f || c[2] != 0.0f; }

}  // namespace

std::uint32_t kernel_features(const std::vector<GpuMaterial>& materials,
                              const std::vector<std::uint32_t>& triangle_flags, const FrameParams& light_params,
                              bool vertex_colours, bool instances, bool punctual_lights) {
  std::uint32_t f = (vertex_colours ? PX_FEATURE_VERTEX_COLOURS : 0u) | (instances ? PX_FEATURE_INSTANCES : 0u) |
                    (punctual_lights ? PX_FEATURE_PUNCTUAL : 0u);
  for (const auto& m : materials) {
    if (m.diffuse_texture >= 0 || m.specular_texture >= 0) f |= PX_FEATURE_TEXTURES;
    if (m.normal_texture >= 0) f |= PX_FEATURE_NORMAL_MAP;
    if (m.flags & PX_MAT_EMISSIVE) f |= PX_FEATURE_EMISSIVE;
    // The kernels read the two-sided flag of emitters only (glTF sets it on every double-sided
    // material).
    if ((m.flags & PX_MAT_EMISSIVE) && (m.flags & PX_MAT_TWO_SIDED_EMITTER)) f |= PX_FEATURE_TWO_SIDED;
    if (m.flags & PX_MAT_DIELECTRIC) {
      f |= PX_FEATURE_DIELECTRIC;
      continue;  // glass has no diffuse or glossy lobe (shading/material.h)
    }
    // As px_make_bsdf decides: a specular lobe is a delta (mirror) with the mirror flag or
    // alpha <= 0, else GGX; without a specular colour it is never sampled (p_specular 0).
    if (!any_positive(m.specular)) continue;
    const bool delta = (m.flags & PX_MAT_MIRROR) != 0u || m.roughness <= 0.0f;
    f |= delta ? PX_FEATURE_MIRROR : PX_FEATURE_GGX;
  }
  if (std::any_of(triangle_flags.begin(), triangle_flags.end(),
                  [](std::uint32_t t) { return (t & PX_TRI_ALPHA_TESTED) != 0u; }))
    f |= PX_FEATURE_ALPHA_TEST;
  if (light_params.light_count > 0 || light_params.p_triangles > 0.0f) f |= PX_FEATURE_EMISSIVE;
  // shading/lights.h reads the sun only where p_sun > 0, the sky's colours always.
  if (light_params.p_sun > 0.0f) f |= PX_FEATURE_SUN;
  if (light_params.p_sky > 0.0f || any_nonzero(light_params.sky_zenith) || any_nonzero(light_params.sky_horizon) ||
      any_nonzero(light_params.sky_ground))
    f |= PX_FEATURE_SKY;
  return f;
}

const std::vector<std::string>& kernel_feature_names() {
  static const std::vector<std::string> names{"textures",       "alpha-test", "dielectric", "mirror", "ggx",
                                              "normal-map",     "emissive",   "two-sided",  "sun",    "sky",
                                              "vertex-colours", "instances",  "punctual"};
  return names;
}

std::vector<std::string> kernel_feature_list(std::uint32_t features) {
  std::vector<std::string> out;
  const auto& names = kernel_feature_names();
  for (std::size_t i = 0; i < names.size(); ++i)
    if (features & (1u << i)) out.push_back(names[i]);
  return out;
}

std::string describe_kernel_features(std::uint32_t features) {
  std::string s;
  for (const auto& n : kernel_feature_list(features)) s += (s.empty() ? "" : ", ") + n;
  return s.empty() ? "none" : s;
}

}  // namespace px
