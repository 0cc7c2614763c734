// The conversion of a parsed glTF model into a Scene (load_gltf, gltf_loader.cpp, drives it):
// Converter's members are defined by part, materials in gltf_materials.cpp, nodes, meshes and
// their placement in gltf_scene.cpp, skins and animations in gltf_animation.cpp.
#pragma once

#include "scene/gltf_reader.h"
#include "scene/scene.h"
#include "scene/scene_loader.h"
#include "scene/scene_rig.h"

#include <tiny_gltf.h>

#include <glm/glm.hpp>

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace px::gltf {

// What the file asks for but is not rendered, gathered into one warning line.
class Unsupported {
 public:
  void add(const std::string& feature, const std::string& where = "") {
    auto [it, inserted] = features_.try_emplace(feature);
    if (inserted) order_.push_back(feature);
    if (!where.empty() && std::find(it->second.begin(), it->second.end(), where) == it->second.end())
      it->second.push_back(where);
  }
  std::string line(const std::string& path) const {
    if (order_.empty()) return {};
    std::string out = path + ": ignored glTF features (not rendered):";
    for (std::size_t i = 0; i < order_.size(); ++i) {
      const auto& where = features_.at(order_[i]);
      out += (i ? ", " : " ") + order_[i];
      if (where.empty()) continue;
      out += " (";
      const std::size_t shown = std::min<std::size_t>(where.size(), 3);
      for (std::size_t k = 0; k < shown; ++k) out += (k ? ", " : "") + where[k];
      if (where.size() > shown) out += ", +" + std::to_string(where.size() - shown) + " more";
      out += ")";
    }
    return out;
  }

 private:
  std::vector<std::string> order_;
  std::map<std::string, std::vector<std::string>> features_;
};

// Converts a parsed model into `scene`, called in this order: materials(), geometry(), finish().
class Converter {
 public:
  Converter(const tinygltf::Model& model, std::string path, const SceneLoadOptions& options, Scene& scene)
      : model_(model), path_(std::move(path)), options_(options), scene_(scene), read_(model_, path_) {}

  void materials();
  void geometry(bool* has_camera);
  void finish();
  static bool handled_extension(const std::string& e);

  std::vector<std::string> failed_images_;
  // Frees the model's buffer bytes (load_gltf owns the model); called once a static scene's
  // meshes are decoded. A later read of an accessor would then fail as out of range, not
  // read stale bytes.
  std::function<void()> release_buffers_;

 private:
  // --- materials (gltf_materials.cpp) ----------------------------------------------------------

  static double number_in(const tinygltf::ExtensionMap& ext, const std::string& name, const std::string& key,
                          double fallback);
  static float finite_clamped(double v, float lo, float hi, float fallback);

  // The image behind texture `index`, or null (with a warning when the reason is not already
  // given elsewhere). `what` names the slot, `mat` the material.
  const tinygltf::Image* texture_image(const tinygltf::TextureInfo& info, const std::string& what,
                                       const std::string& mat);
  const tinygltf::Image* texture_image(int index, int tex_coord, const tinygltf::ExtensionMap& ext,
                                       const std::string& what, const std::string& mat);
  int colour_texture(const tinygltf::Image* img, bool srgb);
  Material material(std::size_t index);

  // The cut-out texture of an alpha-masked material. The renderer cuts out where the
  // (bilinearly filtered) texture's alpha is below 0.5, so alpha = base factor x texel alpha
  // is remapped piecewise linearly to put the material's cutoff at 0.5.
  int mask_texture(const tinygltf::Image* img, float factor, float cutoff, const std::string& mat);

  // --- nodes and meshes (gltf_scene.cpp) -------------------------------------------------------

  // The node's rest transform as the file gives it: a matrix, or translation, rotation
  // (normalised) and scale.
  RigNode node_transform(const tinygltf::Node& n, const std::string& where) const;
  static glm::dmat4 local_matrix(const RigNode& n);

  // Node chains are followed by recursion: bounded, so a file cannot overflow the stack.
  static constexpr int kMaxNodeDepth = 256;

  void visit(int index, const glm::dmat4& parent, int parent_index, const std::string& from, int depth);
  void camera(int index, const glm::dmat4& world, const std::string& where, int node);

  // KHR_lights_punctual. The first directional light becomes the sun (its illuminance, lux,
  // spread over the sun disk's solid angle as radiance); point and spot lights become
  // Scene::punctual_lights (candela as W/sr; `range` ignored, named in the warning line). Each is
  // placed at the node's rest pose; in a scene that moves, a clip that moves the node moves it
  // (SceneRig::sun_node, SceneRig::light_nodes, SceneAnimator).
  void light(int index, const glm::dmat4& world, const std::string& where, int node);
  // A point or spot light: onto Scene::punctual_lights, its node onto SceneRig::light_nodes.
  void punctual_light(const tinygltf::Light& l, int index, const glm::dmat4& world, const std::string& where, int node);

  std::uint32_t default_material();
  void mesh(int index, const glm::dmat4& world, const std::string& where, int node, int skin);

  // The primitives of mesh `index` in its own space (read once, whichever nodes draw it).
  const std::vector<RigPrimitive>& mesh_primitives(int index);

  // Emits every mesh a node draws, in the order the nodes were visited. A mesh that two or more
  // nodes draw becomes instances (Scene::instancing: one copy in its own space, a matrix per
  // node), unless it emits light (the light table samples emitters by their world triangles)
  // or the options ask for flat copies. A node whose transform mirrors draws its own flat
  // copy (turning the winding round is done per triangle, as emit_primitive does).
  void place_meshes();

  // Primitive `pi` of mesh `index` in its own space, or nothing (with a warning) when it is not
  // made of triangles.
  std::optional<RigPrimitive> primitive(int index, std::size_t pi);

  // --- skins and animations, a scene with a rig only (gltf_animation.cpp) ----------------------

  void skins();
  void animations();

  // The scene's triangles at the rest pose (the nodes' own transforms, skins bound by them):
  // the triangles kept here are the rig's for good. A scene without clips keeps no rig.
  void pose_at_rest();

  const tinygltf::Model& model_;
  std::string path_;
  SceneLoadOptions options_;
  Scene& scene_;
  Reader read_;
  Unsupported unsupported_;
  std::map<std::pair<const tinygltf::Image*, bool>, int> cache_;
  std::vector<char> visited_;
  // Scene::vertex_colours while any primitive of the file has COLOR_0, else null.
  std::vector<std::array<glm::vec3, 3>>* colours_out();
  int any_colours_ = 0;                         // bit 0: the file has COLOR_0; bit 1: the file was looked at
  std::shared_ptr<SceneRig> rig_;               // while loading a scene that moves or is skinned
  std::map<int, std::vector<int>> rig_meshes_;  // glTF mesh -> its primitives in the rig
  // A static scene's meshes as the nodes place them (emitted by place_meshes), and each mesh's
  // primitives read once.
  struct Placement {
    int mesh;
    glm::dmat4 world;
  };
  std::vector<Placement> placements_;
  std::map<int, std::vector<RigPrimitive>> static_meshes_;
  int default_material_ = -1;
  bool camera_found_ = false;
};

}  // namespace px::gltf
