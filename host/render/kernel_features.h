// The scene features a kernel build carries (PX_FEATURE_* in kernels/shared/types.h). The
// scene-dependent kernels (path tracers, G-buffer, trace, preview) are compiled with
// -DPX_FEATURES=<the scene's features>, so a Cornell box's kernels hold no texture lookups,
// cut-out tests, glass, normal maps, sun or sky. Each feature is derived from exactly the data
// the kernels test at run time (the uploaded materials, triangle flags and light parameters),
// so a feature left out is one whose branch no pixel could have taken: images are bit-identical
// to the general build (KernelChoice::General, every feature), which tests check.
#pragma once

#include "shared/types.h"

#include <cstdint>
#include <string>
#include <vector>

namespace px {

// --kernels: `scene` compiles only the loaded scene's features in, `general` every feature.
enum class KernelChoice { Scene, General };

// The PX_FEATURE_* bits that branches in the kernels can take for this scene data
// (`vertex_colours`: the scene has per-vertex colours, Scene::vertex_colours; `instances`: it
// has instances, Scene::instancing; `punctual_lights`: its light table holds point or spot
// lights, has_punctual_lights).
std::uint32_t kernel_features(const std::vector<GpuMaterial>& materials,
                              const std::vector<std::uint32_t>& triangle_flags, const FrameParams& light_params,
                              bool vertex_colours = false, bool instances = false, bool punctual_lights = false);

// Feature names in bit order ("textures", "alpha-test", ...), and of a mask.
const std::vector<std::string>& kernel_feature_names();
std::vector<std::string> kernel_feature_list(std::uint32_t features);
// "emissive, ggx" (or "none"): for the console.
std::string describe_kernel_features(std::uint32_t features);

}  // namespace px
