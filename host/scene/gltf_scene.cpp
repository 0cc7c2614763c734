// The node walk of a glTF scene: transforms, cameras, lights, meshes and their primitives, and
// a static scene's meshes placed as flat copies or instances.
#include "scene/gltf_converter.h"

#include "io/free_heap.h"

#include "scene/primitives.h"
#include "scene/punctual_light.h"
#include "scene/sun_path.h"

#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <cmath>
#include <limits>
#include <numbers>
#include <set>

namespace px::gltf {

void Converter::geometry(bool* has_camera) {
  std::vector<int> roots;
  if (!model_.scenes.empty()) {
    int s = model_.defaultScene;
    if (s < 0 || std::size_t(s) >= model_.scenes.size()) s = 0;
    roots = model_.scenes[std::size_t(s)].nodes;
    if (model_.scenes.size() > 1)
      unsupported_.add("scenes other than the default (" + std::to_string(model_.scenes.size() - 1) + ")");
  } else {
    // No scene: every node that is no other node's child is a root.
    std::vector<char> child(model_.nodes.size(), 0);
    for (const tinygltf::Node& n : model_.nodes)
      for (int c : n.children)
        if (c >= 0 && std::size_t(c) < child.size()) child[std::size_t(c)] = 1;
    for (std::size_t i = 0; i < model_.nodes.size(); ++i)
      if (!child[i]) roots.push_back(int(i));
  }
  // A scene that moves keeps its hierarchy, meshes, skins and clips (scene_rig.h) and is
  // posed from them; so is one with skins, posed once at rest. Any other is flattened here.
  bool skinned = false;
  for (const tinygltf::Node& n : model_.nodes) skinned |= n.skin >= 0 && n.mesh >= 0;
  if (!model_.animations.empty() || skinned) {
    rig_ = std::make_shared<SceneRig>();
    rig_->nodes.resize(model_.nodes.size());
  }
  visited_.assign(model_.nodes.size(), 0);
  for (int r : roots) visit(r, glm::dmat4(1.0), -1, "scene", 0);
  if (has_camera) *has_camera = camera_found_;
  if (rig_) {
    skins();
    animations();
    pose_at_rest();
  } else {
    place_meshes();
  }
}

void Converter::finish() {
  for (const std::string& e : model_.extensionsUsed)
    if (!handled_extension(e)) unsupported_.add("extension " + e);
  if (!failed_images_.empty()) {
    std::string list;
    for (const std::string& f : failed_images_) list += (list.empty() ? "" : ", ") + f;
    scene_.stats.warnings.push_back(path_ + ": cannot decode " + list + "; textures using them are ignored");
  }
  if (const std::string line = unsupported_.line(path_); !line.empty()) scene_.stats.warnings.push_back(line);
}

bool Converter::handled_extension(const std::string& e) {
  return e == "KHR_materials_emissive_strength" || e == "KHR_materials_transmission" || e == "KHR_materials_ior" ||
         e == "KHR_lights_punctual";
}

RigNode Converter::node_transform(const tinygltf::Node& n, const std::string& where) const {
  RigNode out;
  if (n.matrix.size() == 16) {
    out.has_matrix = true;
    for (int i = 0; i < 16; ++i) glm::value_ptr(out.matrix)[i] = n.matrix[std::size_t(i)];  // column-major, as glTF
    return out;
  }
  if (!n.matrix.empty()) read_.fail(where + ": matrix must have 16 numbers");
  if (n.translation.size() == 3)
    out.translation = glm::dvec3(n.translation[0], n.translation[1], n.translation[2]);
  else if (!n.translation.empty())
    read_.fail(where + ": translation must have 3 numbers");
  if (n.scale.size() == 3)
    out.scale = glm::dvec3(n.scale[0], n.scale[1], n.scale[2]);
  else if (!n.scale.empty())
    read_.fail(where + ": scale must have 3 numbers");
  if (n.rotation.size() == 4) {
    glm::dquat r(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);  // glTF stores x, y, z, w
    const double len = glm::length(r);
    if (!(len > 0.0) || !std::isfinite(len)) read_.fail(where + ": rotation is not a usable quaternion");
    out.rotation = r / len;
  } else if (!n.rotation.empty()) {
    read_.fail(where + ": rotation must have 4 numbers");
  }
  return out;
}

glm::dmat4 Converter::local_matrix(const RigNode& n) {
  return n.has_matrix ? n.matrix : trs_matrix(n.translation, n.rotation, n.scale);
}

void Converter::visit(int index, const glm::dmat4& parent, int parent_index, const std::string& from, int depth) {
  if (index < 0 || std::size_t(index) >= model_.nodes.size())
    read_.fail(from + " names node " + std::to_string(index) + ", which does not exist");
  if (depth >= kMaxNodeDepth)
    read_.fail("node hierarchy deeper than " + std::to_string(kMaxNodeDepth) + " levels (at node " +
               std::to_string(index) + ")");
  const std::string where = "node " + std::to_string(index);
  if (visited_[std::size_t(index)])
    read_.fail(where + " is reached twice in the node hierarchy (a cycle or a shared child)");
  visited_[std::size_t(index)] = 1;
  const tinygltf::Node& n = model_.nodes[std::size_t(index)];
  RigNode rest = node_transform(n, where);
  const glm::dmat4 world = parent * local_matrix(rest);
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(world[c][r])) read_.fail(where + ": its transform is not finite");
  if (rig_) {
    rest.parent = parent_index;
    rig_->nodes[std::size_t(index)] = rest;
    rig_->order.push_back(index);
  }
  if (n.camera >= 0) camera(n.camera, world, where, index);
  if (n.mesh >= 0) mesh(n.mesh, world, where, index, n.skin);
  for (const auto& [ext, value] : n.extensions) {
    if (ext == "KHR_lights_punctual" && value.IsObject() && value.Has("light") && value.Get("light").IsInt())
      light(value.Get("light").GetNumberAsInt(), world, where, index);
    else
      unsupported_.add("node extension " + ext, where);
  }
  for (int c : n.children) visit(c, world, index, where, depth + 1);
}

void Converter::camera(int index, const glm::dmat4& world, const std::string& where, int node) {
  if (std::size_t(index) >= model_.cameras.size())
    read_.fail(where + " names camera " + std::to_string(index) + ", which does not exist");
  const tinygltf::Camera& c = model_.cameras[std::size_t(index)];
  if (c.type != "perspective") {
    unsupported_.add("orthographic cameras", where);
    return;
  }
  if (camera_found_) return;  // the first perspective camera is the view
  const double yfov = c.perspective.yfov;
  if (!(yfov > 0.0 && yfov < std::numbers::pi)) {
    scene_.stats.warnings.push_back(path_ + ": camera " + std::to_string(index) +
                                    " has an unusable yfov; framing the scene instead");
    return;
  }
  if (!camera_from_node(world, scene_.camera)) {
    scene_.stats.warnings.push_back(path_ + ": camera " + std::to_string(index) +
                                    " has a degenerate orientation; framing the scene instead");
    return;
  }
  scene_.camera.vfov_deg = float(glm::degrees(yfov));
  camera_found_ = true;
  if (rig_) rig_->camera_node = node;
}

void Converter::light(int index, const glm::dmat4& world, const std::string& where, int node) {
  if (index < 0 || std::size_t(index) >= model_.lights.size())
    read_.fail(where + " names light " + std::to_string(index) + ", which does not exist");
  const tinygltf::Light& l = model_.lights[std::size_t(index)];
  if (l.type == "point" || l.type == "spot") {
    punctual_light(l, index, world, where, node);
    return;
  }
  if (l.type != "directional") {
    unsupported_.add("lights of type '" + l.type + "' (KHR_lights_punctual)", where);
    return;
  }
  if (scene_.sun.enabled) {
    unsupported_.add("directional lights after the first (KHR_lights_punctual)", where);
    return;
  }
  glm::vec3 towards;
  if (!sun_from_node(world, towards)) {
    scene_.stats.warnings.push_back(path_ + ": " + where + ": directional light with a degenerate direction; ignored");
    return;
  }
  glm::vec3 colour(1.0f);
  for (std::size_t c = 0; c < 3 && c < l.color.size(); ++c)
    colour[int(c)] = finite_clamped(l.color[c], 0.0f, 1.0f, 1.0f);
  const float lux = std::isfinite(l.intensity) && l.intensity > 0.0 ? float(std::min(l.intensity, 1e9)) : 0.0f;
  Sun& sun = scene_.sun;
  sun.enabled = lux > 0.0f;
  sun.direction = towards;
  const double cos_max = std::cos(glm::radians(double(sun.angular_radius_deg)));
  sun.radiance = colour * float(lux / (2.0 * std::numbers::pi * (1.0 - cos_max)));
  // A clip that turns the node (or an ancestor) turns the sun (SceneAnimator).
  if (rig_ && sun.enabled) rig_->sun_node = node;
}

void Converter::punctual_light(const tinygltf::Light& l, int index, const glm::dmat4& world, const std::string& where,
                               int node) {
  PunctualLight light;
  light.spot = l.type == "spot";
  if (!place_light_at_node(world, light)) {
    scene_.stats.warnings.push_back(path_ + ": " + where + ": " + l.type + " light " + std::to_string(index) +
                                    " with a degenerate placement; ignored");
    return;
  }
  glm::vec3 colour(1.0f);
  for (std::size_t c = 0; c < 3 && c < l.color.size(); ++c)
    colour[int(c)] = finite_clamped(l.color[c], 0.0f, 1.0f, 1.0f);
  // Candela taken as W/sr (scene.h, PunctualLight).
  const float candela = std::isfinite(l.intensity) && l.intensity > 0.0 ? float(std::min(l.intensity, 1e9)) : 0.0f;
  light.intensity = colour * candela;
  if (light.spot) {
    // The spec's bounds: 0 <= inner < outer <= pi/2; out-of-range values are clamped into them.
    const double half_pi = std::numbers::pi / 2.0;
    const double outer = std::isfinite(l.spot.outerConeAngle) ? l.spot.outerConeAngle : std::numbers::pi / 4.0;
    const double inner = std::isfinite(l.spot.innerConeAngle) ? l.spot.innerConeAngle : 0.0;
    light.outer_cone_rad = float(std::clamp(outer, 1e-4, half_pi));
    light.inner_cone_rad = float(std::clamp(inner, 0.0, double(light.outer_cone_rad)));
  }
  if (l.range > 0.0) unsupported_.add("light range (lights fall off as 1/d^2 without a cut-off)", where);
  if (!(candela > 0.0f)) return;
  scene_.punctual_lights.push_back(light);
  // A clip that moves the node (or an ancestor) moves the light (SceneAnimator).
  if (rig_) {
    rig_->light_nodes.resize(scene_.punctual_lights.size() - 1, -1);
    rig_->light_nodes.push_back(node);
  }
}

std::uint32_t Converter::default_material() {
  if (default_material_ < 0) {
    // A primitive without a material: the same grey as an OBJ face without one.
    Material grey;
    grey.name = "default";
    grey.diffuse = glm::vec3(0.7f);
    scene_.materials.push_back(grey);
    default_material_ = int(scene_.materials.size()) - 1;
  }
  return std::uint32_t(default_material_);
}

void Converter::mesh(int index, const glm::dmat4& world, const std::string& where, int node, int skin) {
  if (std::size_t(index) >= model_.meshes.size())
    read_.fail(where + " names mesh " + std::to_string(index) + ", which does not exist");
  if (skin >= 0 && std::size_t(skin) >= model_.skins.size())
    read_.fail(where + " names skin " + std::to_string(skin) + ", which does not exist");
  if (rig_) {
    // Posed later (pose_at_rest, and every frame): the primitives are read once per mesh,
    // whichever nodes share it.
    auto [it, fresh] = rig_meshes_.try_emplace(index);
    if (fresh)
      for (std::size_t pi = 0; pi < model_.meshes[std::size_t(index)].primitives.size(); ++pi)
        if (auto prim = primitive(index, pi)) {
          rig_->primitives.push_back(std::move(*prim));
          it->second.push_back(int(rig_->primitives.size()) - 1);
        }
    RigMeshInstance inst;
    inst.node = node;
    inst.skin = skin;
    inst.primitives = it->second;
    if (skin >= 0)
      for (int p : inst.primitives)
        if (rig_->primitives[std::size_t(p)].joints.empty())
          unsupported_.add("skins on primitives without JOINTS_0 and WEIGHTS_0 (rendered unskinned)", where);
    rig_->instances.push_back(std::move(inst));
    return;
  }
  // Placed once every node is visited (place_meshes): a mesh that several nodes draw may be
  // stored once, as instances.
  placements_.push_back({index, world});
}

const std::vector<RigPrimitive>& Converter::mesh_primitives(int index) {
  auto [it, fresh] = static_meshes_.try_emplace(index);
  if (fresh)
    for (std::size_t pi = 0; pi < model_.meshes[std::size_t(index)].primitives.size(); ++pi)
      if (auto prim = primitive(index, pi)) it->second.push_back(std::move(*prim));
  return it->second;
}

void Converter::place_meshes() {
  const bool instancing = options_.instancing;
  std::map<int, int> uses;
  for (const Placement& pl : placements_)
    if (glm::determinant(glm::dmat3(pl.world)) > 0.0) ++uses[pl.mesh];
  std::map<int, bool> instanced;
  for (const auto& [mesh, n] : uses) {
    bool ok = instancing && n >= 2;
    for (const RigPrimitive& prim : mesh_primitives(mesh)) ok &= !scene_.materials.at(prim.material).is_emissive();
    instanced[mesh] = ok;
  }
  std::vector<std::array<glm::vec3, 3>>* colours = colours_out();
  const auto flat = [&](const Placement& pl) {
    const auto it = instanced.find(pl.mesh);
    return it == instanced.end() || !it->second || !(glm::determinant(glm::dmat3(pl.world)) > 0.0);
  };
  // A mesh's primitives are released after its last flat copy (unless it is instanced too), so
  // that a file of many meshes holds one at a time, as it did before placements were deferred.
  std::map<int, int> copies_left;
  for (const Placement& pl : placements_)
    if (flat(pl)) ++copies_left[pl.mesh];
  {
    // Room for every triangle at once: growing a 10M-triangle array by doubling had copied it
    // and touched twice its memory.
    std::size_t expected = scene_.triangles.size();
    std::set<int> stored;  // an instanced mesh is stored once
    for (const Placement& pl : placements_)
      if (flat(pl) || stored.insert(pl.mesh).second)
        for (const RigPrimitive& prim : mesh_primitives(pl.mesh)) expected += prim.triangles.size();
    scene_.triangles.reserve(expected);
    // Every mesh a node draws is decoded now (the count above): the file's buffers are read no
    // more, and go before the triangles are made, at the load's highest point (docs/measurements.md,
    // glTF load memory); so does the heap the decoding freed (each accessor's floats were read
    // into a temporary array first: io/free_heap.h).
    if (release_buffers_) release_buffers_();
    give_back_free_heap(expected);
  }
  for (const Placement& pl : placements_) {
    if (!flat(pl)) continue;
    if (copies_left[pl.mesh] == 1 && !instanced[pl.mesh]) {
      // Its last copy: the vertices turn to world space in their own arrays.
      mesh_primitives(pl.mesh);
      for (RigPrimitive& prim : static_meshes_.at(pl.mesh))
        emit_last_copy(prim, pl.world, scene_.triangles, scene_.stats, colours);
    } else {
      for (const RigPrimitive& prim : mesh_primitives(pl.mesh))
        emit_primitive(prim, pl.world, nullptr, nullptr, nullptr, scene_.triangles, scene_.stats, colours);
    }
    if (--copies_left[pl.mesh] == 0 && !instanced[pl.mesh]) static_meshes_.erase(pl.mesh);
  }
  SceneInstancing in;
  in.world_triangles = scene_.triangles.size();
  std::map<int, std::uint32_t> mesh_slot;
  for (const Placement& pl : placements_) {
    if (flat(pl)) continue;
    auto [slot, fresh] = mesh_slot.try_emplace(pl.mesh, std::uint32_t(in.meshes.size()));
    if (fresh) {
      InstancedMesh m;
      m.first = scene_.triangles.size();
      for (const RigPrimitive& prim : mesh_primitives(pl.mesh))
        emit_primitive(prim, glm::dmat4(1.0), nullptr, nullptr, nullptr, scene_.triangles, scene_.stats, colours);
      m.count = scene_.triangles.size() - m.first;
      static_meshes_.erase(pl.mesh);  // stored: its primitives are no longer needed
      if (m.count == 0) {             // nothing drawable: no instances either
        slot->second = std::numeric_limits<std::uint32_t>::max();
      } else {
        in.meshes.push_back(m);
      }
    }
    if (slot->second == std::numeric_limits<std::uint32_t>::max()) continue;
    MeshInstance inst;
    inst.mesh = slot->second;
    inst.object_to_world = glm::mat4(pl.world);
    in.instances.push_back(inst);
  }
  if (!in.instances.empty()) scene_.instancing = std::move(in);
}

std::optional<RigPrimitive> Converter::primitive(int index, std::size_t pi) {
  const tinygltf::Primitive& prim = model_.meshes[std::size_t(index)].primitives[pi];
  const std::string what = "mesh " + std::to_string(index) + " primitive " + std::to_string(pi);
  if (!prim.targets.empty()) unsupported_.add("morph targets", "mesh " + std::to_string(index));
  for (const auto& [ext, value] : prim.extensions) unsupported_.add("primitive extension " + ext, what);
  const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
  if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN) {
    unsupported_.add(mode == TINYGLTF_MODE_POINTS ? "point primitives" : "line primitives", what);
    return std::nullopt;
  }
  RigPrimitive out;
  const auto pos_it = prim.attributes.find("POSITION");
  if (pos_it == prim.attributes.end()) read_.fail(what + " has no POSITION attribute");
  out.positions = read_.vec3s(pos_it->second, what + " POSITION");
  const std::size_t nv = out.positions.size();
  if (auto it = prim.attributes.find("NORMAL"); it != prim.attributes.end()) {
    out.normals = read_.vec3s(it->second, what + " NORMAL");
    if (out.normals.size() != nv) read_.fail(what + ": NORMAL and POSITION counts differ");
  }
  if (auto it = prim.attributes.find("TEXCOORD_0"); it != prim.attributes.end()) {
    out.uvs = read_.vec2s(it->second, what + " TEXCOORD_0");
    if (out.uvs.size() != nv) read_.fail(what + ": TEXCOORD_0 and POSITION counts differ");
  }
  const auto joints_it = prim.attributes.find("JOINTS_0"), weights_it = prim.attributes.find("WEIGHTS_0");
  if (rig_ && joints_it != prim.attributes.end() && weights_it != prim.attributes.end()) {
    out.joints = read_.floats(joints_it->second, {TINYGLTF_TYPE_VEC4}, what + " JOINTS_0", true);
    out.weights = read_.floats(weights_it->second, {TINYGLTF_TYPE_VEC4}, what + " WEIGHTS_0", true);
    if (out.joints.size() != nv || out.weights.size() != nv)
      read_.fail(what + ": JOINTS_0, WEIGHTS_0 and POSITION counts differ");
  }
  for (const auto& [attr, acc] : prim.attributes)
    if (attr.rfind("JOINTS_", 0) == 0 || attr.rfind("WEIGHTS_", 0) == 0) {
      if (attr != "JOINTS_0" && attr != "WEIGHTS_0")
        unsupported_.add("more than four joints per vertex", what);
      else if (!rig_)
        unsupported_.add("skins", what);
    } else if (attr.rfind("COLOR_", 0) == 0 && attr != "COLOR_0") {
      unsupported_.add("vertex colour sets other than COLOR_0", what);
    }
  if (auto it = prim.attributes.find("COLOR_0"); it != prim.attributes.end()) {
    // Linear RGB(A), floats or normalised integers; alpha is not rendered.
    const auto colours = read_.floats(it->second, {TINYGLTF_TYPE_VEC3, TINYGLTF_TYPE_VEC4}, what + " COLOR_0", true);
    if (colours.size() != nv) read_.fail(what + ": COLOR_0 and POSITION counts differ");
    out.colours.resize(nv);
    for (std::size_t v = 0; v < nv; ++v) {
      const glm::vec4& c = colours[v];
      for (int k = 0; k < 3; ++k) out.colours[v][k] = std::isfinite(c[k]) ? std::clamp(c[k], 0.0f, 1.0f) : 1.0f;
    }
  }

  std::vector<std::uint32_t> idx;
  if (prim.indices >= 0) {
    idx = read_.indices(prim.indices, what + " indices");
    for (std::size_t i = 0; i < idx.size(); ++i)
      if (idx[i] >= nv)
        read_.fail(what + ": index " + std::to_string(idx[i]) + " (at " + std::to_string(i) + ") is out of range (" +
                   std::to_string(nv) + " vertices)");
  } else {
    idx.resize(nv);
    for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = std::uint32_t(i);
  }
  auto& tris = out.triangles;
  // At its final size from the start: grown by doubling, a large mesh's list was made about
  // twice over in fresh memory.
  tris.reserve(mode == TINYGLTF_MODE_TRIANGLES ? idx.size() / 3 : idx.size() > 2 ? idx.size() - 2 : 0);
  if (mode == TINYGLTF_MODE_TRIANGLES) {
    for (std::size_t i = 0; i + 2 < idx.size(); i += 3) tris.push_back({idx[i], idx[i + 1], idx[i + 2]});
  } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
    for (std::size_t i = 0; i + 2 < idx.size(); ++i)
      tris.push_back(i % 2 == 0 ? std::array{idx[i], idx[i + 1], idx[i + 2]}
                                : std::array{idx[i + 1], idx[i], idx[i + 2]});
  } else {
    for (std::size_t i = 1; i + 1 < idx.size(); ++i) tris.push_back({idx[0], idx[i], idx[i + 1]});
  }

  if (prim.material >= 0 && std::size_t(prim.material) < model_.materials.size())
    out.material = std::uint32_t(prim.material);
  else {
    if (prim.material >= 0)
      scene_.stats.warnings.push_back(path_ + ": " + what + " names material " + std::to_string(prim.material) +
                                      ", which does not exist; using a default grey");
    out.material = default_material();
  }
  return out;
}

std::vector<std::array<glm::vec3, 3>>* Converter::colours_out() {
  if (!any_colours_) {
    for (const tinygltf::Mesh& m : model_.meshes)
      for (const tinygltf::Primitive& p : m.primitives) any_colours_ |= p.attributes.count("COLOR_0") ? 1 : 0;
    any_colours_ |= 2;  // looked
  }
  return (any_colours_ & 1) ? &scene_.vertex_colours : nullptr;
}

}  // namespace px::gltf
