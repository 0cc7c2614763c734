#include "render/scene_animator.h"

#include "bvh/bvh_builder.h"
#include "bvh/bvh_refit.h"
#include "bvh/bvh_validator.h"
#include "bvh/wide_bvh.h"
#include "scene/punctual_light.h"
#include "scene/scene_rig.h"
#include "scene/sun_path.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <stdexcept>

namespace px {
namespace {

using clock_type = std::chrono::steady_clock;
double ms_since(clock_type::time_point t0) {
  return std::chrono::duration<double, std::milli>(clock_type::now() - t0).count();
}

}  // namespace

SceneAnimator::SceneAnimator(Scene& scene, const std::string& choice)
    : scene_(scene), base_camera_(scene.camera), base_sun_(scene.sun) {
  // A scene file's sun keys play whatever --animation says, as its camera path does.
  if (scene.sun.enabled) sun_keys_ = scene.sun_path;
  if (!scene.rig) {
    if (!choice.empty() && choice != "all" && choice != "none")
      throw std::invalid_argument("--animation " + choice + ": the scene " + scene.name + " has no animations");
    moves_ = !sun_keys_.empty();
    return;
  }
  const SceneRig& rig = *scene.rig;
  clips_ = select_clips(rig.clips, choice);
  moves_ = rig_moves(rig, clips_) || !sun_keys_.empty();
  // The glTF camera follows its node unless a scene file placed the camera itself.
  if (rig.camera_node >= 0 && scene.camera_path.empty()) {
    const Camera rest = rig_camera(rig, rig_world_matrices(rig, 0.0, {}), scene.camera);
    follow_camera_ = rest.position == scene.camera.position && rest.target == scene.camera.target;
  }
  const std::vector<char> moving = moving_nodes(rig, clips_);
  const auto moved = [&](int node) {
    return node >= 0 && static_cast<std::size_t>(node) < moving.size() && moving[static_cast<std::size_t>(node)];
  };
  // The glTF sun follows its node unless a scene file gave the sun keys or its own direction.
  if (moved(rig.sun_node) && sun_keys_.empty() && scene.sun.enabled) {
    glm::vec3 rest;
    sun_follows_node_ = sun_from_node(rig_world_matrices(rig, 0.0, {})[static_cast<std::size_t>(rig.sun_node)], rest) &&
                        rest == scene.sun.direction;
  }
  // glTF point and spot lights follow their nodes; a frame where only they move rewrites the
  // light table alone (DeviceScene::update_lights).
  for (std::size_t i = 0; i < rig.light_nodes.size() && i < scene.punctual_lights.size(); ++i)
    if (moved(rig.light_nodes[i])) moving_lights_.push_back(i);
  moves_ = moves_ || !moving_lights_.empty();
  base_lights_ = scene.punctual_lights;
  // Only what the devices' geometry holds needs it rewritten: a clip that moves nothing but the
  // sun (and nodes that carry nothing) leaves the triangles as loaded. A moving camera keeps
  // the rewrite it always had (its frames' motion buffers).
  geometry_moves_ = moved(rig.camera_node);
  for (const RigMeshInstance& inst : rig.instances) {
    geometry_moves_ |= moved(inst.node);
    if (inst.skin >= 0 && static_cast<std::size_t>(inst.skin) < rig.skins.size())
      for (int j : rig.skins[static_cast<std::size_t>(inst.skin)].joints) geometry_moves_ |= moved(j);
  }
}

std::string SceneAnimator::describe() const {
  std::string sun;
  if (!sun_keys_.empty()) {
    char keys[96];
    std::snprintf(keys, sizeof keys, "the sun's %zu keys (%.2f s, then held)", sun_keys_.size(),
                  double(sun_keys_.back().time));
    sun = keys;
  }
  if (!scene_.rig || clips_.empty()) {
    if (!sun.empty()) return sun;
    return scene_.rig ? "none (the rest pose)" : "none (static scene)";
  }
  std::string out = sun;
  for (int c : clips_) {
    const AnimationClip& clip = scene_.rig->clips[static_cast<std::size_t>(c)];
    char len[32];
    std::snprintf(len, sizeof len, " (%.2f s)", clip.duration);
    out += (out.empty() ? "'" : ", '") + clip.name + "'" + len;
  }
  return out + ", looping" + (sun_follows_node_ ? " (turning the sun)" : "");
}

void SceneAnimator::pose(double time_s) {
  if (!moves_) return;
  if (!sun_keys_.empty()) scene_.sun = moving_sun(base_sun_, sun_path_direction(sun_keys_, time_s));
  if (!scene_.rig || !(geometry_moves_ || follow_camera_ || sun_follows_node_ || !moving_lights_.empty())) return;
  const std::vector<glm::dmat4> world = rig_world_matrices(*scene_.rig, time_s, clips_);
  for (std::size_t i : moving_lights_) {
    PunctualLight light = base_lights_[i];
    // A pose that makes the node degenerate leaves the light where it rests.
    place_light_at_node(world[static_cast<std::size_t>(scene_.rig->light_nodes[i])], light);
    scene_.punctual_lights[i] = light;
  }
  glm::vec3 towards;
  if (sun_follows_node_ && sun_from_node(world[static_cast<std::size_t>(scene_.rig->sun_node)], towards))
    scene_.sun = moving_sun(base_sun_, towards);
  if (follow_camera_) scene_.camera = rig_camera(*scene_.rig, world, base_camera_);
  if (!geometry_moves_) return;
  if (scene_.instancing.empty()) {
    pose_rig(*scene_.rig, world, scene_.triangles);
    return;
  }
  // The world's triangles come first in scene.triangles; the instances' meshes after them never
  // change (their matrices move them).
  pose_rig(*scene_.rig, world, world_);
  if (world_.size() != scene_.instancing.world_triangles)
    throw std::logic_error("SceneAnimator: the posed world has another triangle count");
  std::copy(world_.begin(), world_.end(), scene_.triangles.begin());
  rig_instance_matrices(*scene_.rig, world, scene_.instancing);
}

SceneAnimator::Update SceneAnimator::update(double time_s, DeviceSet& devices, DeviceScene& device_scene) {
  Update u;
  if (!moves_) return u;
  auto t0 = clock_type::now();
  pose(time_s);
  u.pose_ms = ms_since(t0);
  if (!geometry_moves_) {
    // The sun alone: the next launch's FrameParams carry it. Point and spot lights: their table.
    if (!moving_lights_.empty()) {
      t0 = clock_type::now();
      u.bytes = device_scene.update_lights(devices, scene_);
      u.upload_ms = ms_since(t0);
    }
    return u;
  }
  t0 = clock_type::now();
  // The world tree covers the world's own triangles: all of them, or those before the
  // instances' meshes (none: no world tree; the instances' top level is built with the upload).
  const bool instanced = !scene_.instancing.empty();
  const std::vector<SceneTriangle>& world = instanced ? world_ : scene_.triangles;
  bool rebuild = false;
  if (!world.empty()) {
    rebuild = bvh_.nodes.empty();
    if (!rebuild) {
      refit_bvh(bvh_, world);
      rebuild = !(bvh_.stats.sah_cost <= kRebuildGrowth * built_sah_);
    }
    if (rebuild) {
      BvhBuildOptions options;
      options.spatial_splits = false;  // leaves of whole triangles, which refit_bvh can refit
      bvh_ = build_bvh(world, options);
      const BvhValidation check = validate_bvh(bvh_, world);
      if (!check.ok)
        throw std::runtime_error("internal error: the BVH of the posed scene at t = " + std::to_string(time_s) +
                                 " s failed validation: " + (check.errors.empty() ? "" : check.errors.front()));
      built_sah_ = bvh_.stats.sah_cost;
    }
    ensure_layout(bvh_, device_scene.layout());  // the wide nodes, collapsed anew after a refit
  }
  u.rebuilt = rebuild;
  u.bvh_ms = ms_since(t0);
  t0 = clock_type::now();
  // The first frame has no previous pose: its motion is none (the history is empty anyway).
  std::vector<glm::mat4> matrices;
  for (const MeshInstance& inst : scene_.instancing.instances) matrices.push_back(inst.object_to_world);
  u.bytes = device_scene.update_geometry(devices, scene_, bvh_, previous_.empty() ? &scene_.triangles : &previous_,
                                         previous_matrices_.empty() ? &matrices : &previous_matrices_);
  u.upload_ms = ms_since(t0);
  previous_ = scene_.triangles;
  previous_matrices_ = std::move(matrices);
  return u;
}

}  // namespace px
