// The in-memory scene: triangles with shading attributes, materials, textures, camera and
// lights. Everything the renderer needs, independent of where it came from (an OBJ file or a
// built-in generator). Loaders fill it; the BVH builder and the device uploader read it.
#pragma once

#include <glm/glm.hpp>

#include <array>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace px {

struct SceneRig;  // scene_rig.h

// Any failure to produce a valid scene. The message names the file (and line, where there is
// one) and says what is wrong, so the CLI can print it as is and exit non-zero.
struct SceneError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// RGBA float texture, linear colour (sRGB images are converted on load), rows top to bottom.
struct Texture {
  std::string path;
  int width = 0;
  int height = 0;
  std::vector<float> rgba;  // width * height * 4
};

// Material as the scenes need it (OBJ/MTL mapping in parentheses):
// Lambertian diffuse (Kd, map_Kd), a GGX glossy lobe (Ks, map_Ks, Ns -> roughness), a perfect
// mirror (Ks with very high Ns, or illum 3/5 with Ks), a smooth dielectric (glass: illum 4/6/7,
// d < 1 or a transmission filter Tf; index of refraction Ni), tangent-space normal maps (norm,
// or bump naming a normal map), alpha cut-outs (map_d), emission (Ke, from the front face
// unless the scene file asks for two-sided emitters).
struct Material {
  std::string name;
  glm::vec3 diffuse{0.8f};       // Kd, linear albedo
  glm::vec3 specular{0.0f};      // Ks
  float roughness = 1.0f;        // GGX alpha derived from Ns; 0 = perfect mirror
  glm::vec3 emission{0.0f};      // Ke, radiance
  int diffuse_texture = -1;      // index into Scene::textures, -1 = none
  int specular_texture = -1;     // map_Ks: multiplies `specular`
  int normal_texture = -1;       // tangent-space normal map (linear RGB, (0.5, 0.5, 1) = flat)
  float normal_scale = 1.0f;     // -bm: scales the map's tangent-plane components
  int alpha_texture = -1;        // map_d; texels with alpha < 0.5 are cut out
  bool mirror = false;           // perfect specular reflection
  bool dielectric = false;       // smooth glass: Fresnel reflection + refraction
  float ior = 1.5f;              // Ni, dielectric only: index inside relative to outside
  glm::vec3 transmission{1.0f};  // Tf, dielectric only: filter on refracted light
  bool two_sided = false;        // emits from both faces (default: only from the front face, the
                                 // side the winding order's normal points to)
  bool is_emissive() const { return emission.x > 0.0f || emission.y > 0.0f || emission.z > 0.0f; }
};

// One triangle with its shading attributes. Normals are always present (geometric normal when
// the source had none); uvs are zero when absent.
struct SceneTriangle {
  glm::vec3 p[3];
  glm::vec3 n[3];
  glm::vec2 uv[3];
  std::uint32_t material = 0;
};

struct Camera {
  glm::vec3 position{0.0f, 0.0f, 5.0f};
  glm::vec3 target{0.0f};
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  float vfov_deg = 45.0f;  // vertical field of view
};

// One keyframe of a camera path; the path is evaluated by time in seconds (linear
// interpolation of position and target between keys; before the first / after the last key
// it holds).
struct CameraKey {
  float time = 0.0f;
  glm::vec3 position{0.0f};
  glm::vec3 target{0.0f};
};

struct Sun {
  bool enabled = false;
  glm::vec3 direction{0.0f, 1.0f, 0.0f};  // unit vector pointing towards the sun
  glm::vec3 radiance{0.0f};               // radiance of the sun disk
  float angular_radius_deg = 0.27f;
};

// One keyframe of a scene file's moving sun (its "sun": {"keys": [...]}); the direction is
// evaluated by time in seconds on the animation's clock (sun_path.h: along the great circle
// between keys; before the first / after the last key it holds).
struct SunKey {
  float time = 0.0f;
  glm::vec3 direction{0.0f, 1.0f, 0.0f};  // unit vector towards the sun
};

// A point or spot light (glTF KHR_lights_punctual on a node, or a scene file's "lights" entry).
// `intensity` is radiant intensity in the renderer's radiometric units (W/sr): glTF's candela
// times the light's colour, taken as they are, as emission radiance and the sun's radiance are
// (nothing here converts photometric units). A point light shines alike in every direction; a
// spot light along `direction` with glTF's smooth falloff between the cones: full inside
// `inner_cone_rad` of the axis, nothing beyond `outer_cone_rad`, the square of a linear ramp in
// the cosine between. glTF's `range` is ignored: the light falls off as 1 / d^2 everywhere.
struct PunctualLight {
  bool spot = false;
  glm::vec3 position{0.0f};
  glm::vec3 direction{0.0f, -1.0f, 0.0f};  // spot only: unit vector the light shines along
  glm::vec3 intensity{0.0f};               // W/sr, linear RGB
  float inner_cone_rad = 0.0f;             // spot only: 0 <= inner < outer <= pi/2
  float outer_cone_rad = 0.7853982f;       // pi / 4, glTF's default
};

// Simple analytic sky: radiance blends from horizon to zenith by the direction's elevation;
// below the horizon it is `ground`.
struct Sky {
  bool enabled = false;
  glm::vec3 zenith{0.0f};
  glm::vec3 horizon{0.0f};
  glm::vec3 ground{0.0f};
};

// What loading repaired or noticed, reported to the user.
struct SceneStats {
  std::size_t dropped_degenerate = 0;  // zero-area triangles removed
  std::size_t dropped_nonfinite = 0;   // triangles with NaN/Inf coordinates removed
  std::vector<std::string> warnings;   // e.g. "missing texture x.png, material y: using Kd"
};

// Meshes that several glTF nodes draw, stored once (instancing.h). Scene::triangles then holds
// first the world's own triangles (world_triangles of them, in world space), then each mesh's
// triangles in its own space, mesh after mesh; the instances place them in the world.
struct InstancedMesh {
  std::size_t first = 0;  // index of its first triangle in Scene::triangles
  std::size_t count = 0;
};

struct MeshInstance {
  std::uint32_t mesh = 0;           // index into SceneInstancing::meshes
  glm::mat4 object_to_world{1.0f};  // affine, with a positive determinant
};

struct SceneInstancing {
  std::size_t world_triangles = 0;
  std::vector<InstancedMesh> meshes;
  std::vector<MeshInstance> instances;
  bool empty() const { return instances.empty(); }
};

struct Scene {
  std::string name;
  std::vector<SceneTriangle> triangles;
  // Empty, or one entry per triangle: its corners' linear RGB colours (glTF COLOR_0), which
  // multiply the diffuse colour. Kept apart from SceneTriangle so that scenes without vertex
  // colours (most) pay nothing for them.
  std::vector<std::array<glm::vec3, 3>> vertex_colours;
  std::vector<Material> materials;  // at least one
  std::vector<Texture> textures;
  Camera camera;
  std::vector<CameraKey> camera_path;  // empty = static camera
  float meters_per_unit = 1.0f;        // scene units -> metres
  float ipd_m = 0.062f;                // interpupillary distance in metres
  Sun sun;
  std::vector<SunKey> sun_path;  // empty = the sun stays where `sun` puts it (or a glTF clip turns it)
  Sky sky;
  // Point and spot lights; a glTF light on a node a clip moves follows the node
  // (SceneRig::light_nodes, SceneAnimator).
  std::vector<PunctualLight> punctual_lights;
  SceneStats stats;
  // How the scene moves (a glTF file with animations; scene_rig.h), or null for a static scene.
  // `triangles` then hold its rest pose until a SceneAnimator poses them for a frame's time.
  std::shared_ptr<const SceneRig> rig;
  // Meshes drawn by several nodes (a static scene only; never together with `rig`), or empty:
  // then every triangle is in world space.
  SceneInstancing instancing;

  // Interpupillary distance in scene units.
  float ipd_units() const { return ipd_m / meters_per_unit; }
};

}  // namespace px
