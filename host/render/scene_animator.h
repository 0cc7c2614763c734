// Brings an animated scene (Scene::rig) to a frame's time: poses its triangles (and a glTF
// camera on an animated node), rebuilds the BVH over them and rewrites the devices' geometry.
// The sun moves on the same clock: a scene file's sun keys (Scene::sun_path) or a glTF
// directional light on a node a clip turns (sun_path.h); a frame whose only change is the sun
// rewrites no geometry (the kernels read the sun from each launch's FrameParams). glTF point and
// spot lights on moving nodes move too: their light table entries (and the light tree) are
// rewritten each frame, with the geometry or alone.
// One clock: the caller passes frame f's time f / fps, the same in `render`, `reference`,
// `view` and on every MPI rank, so every rank and device poses the same triangles bit for bit.
//
// The tree follows the pose by refitting: the first frame builds a binned-SAH tree (no spatial
// splits, so every leaf holds whole triangles) and validates it; later frames recompute its
// boxes around the moved triangles (refit_bvh), until its SAH cost has grown past
// kRebuildGrowth x the cost it was built with, when it is built anew. Rigid meshes on moving
// nodes are instances (Scene::instancing): only their matrices change, and the top level over
// them is rebuilt with the upload. Only the pieces of the device buffers that changed are
// written. What that costs is measured per frame (Update) and reported.
#pragma once

#include "bvh/flat_bvh.h"
#include "cl/device_set.h"
#include "render/device_scene.h"
#include "scene/scene.h"

#include <string>
#include <vector>

namespace px {

class SceneAnimator {
 public:
  // `choice` is --animation: "all" (default), "none", a clip's name or index. Throws
  // std::invalid_argument naming the scene's clips when there is no such clip.
  SceneAnimator(Scene& scene, const std::string& choice);

  // Whether the selected clips move anything or the scene's sun has keys: when not, update()
  // does nothing and the scene stays as loaded (its rest pose).
  bool moves() const { return moves_; }
  // Whether the sun moves (keys, or a clip turning the glTF light's node).
  bool sun_moves() const { return !sun_keys_.empty() || sun_follows_node_; }
  // Names of the clips that play, for the console.
  std::string describe() const;

  // Poses scene.triangles (and the camera, where it is an animated glTF camera, and the sun,
  // where it moves) at `time_s`, on the host only: the reference renderer and the preview,
  // which build their BVH after.
  void pose(double time_s);

  struct Update {
    double pose_ms = 0.0, bvh_ms = 0.0, upload_ms = 0.0;
    std::size_t bytes = 0;  // written to the devices' context
    bool rebuilt = false;   // the tree was built anew (else refitted)
  };
  // How much a refitted tree's SAH cost may grow over its build's before it is rebuilt.
  static constexpr double kRebuildGrowth = 1.3;
  // pose(), then a BVH over the posed triangles and the devices' geometry rewritten, with the
  // last frame's positions as motion (the first call: none, so no motion). Call between
  // frames, with every queue finished.
  Update update(double time_s, DeviceSet& devices, DeviceScene& device_scene);

 private:
  Scene& scene_;
  std::vector<int> clips_;
  bool moves_ = false;
  bool geometry_moves_ = false;             // a clip moves a mesh, a skin's joint or the camera (not only the sun)
  bool follow_camera_ = false;              // the scene's camera is the rig's glTF camera
  bool sun_follows_node_ = false;           // the scene's sun is the rig's glTF light, on a node a clip moves
  std::vector<SunKey> sun_keys_;            // the scene file's sun keys (they win over a glTF light)
  std::vector<std::size_t> moving_lights_;  // Scene::punctual_lights on nodes a clip moves
  std::vector<PunctualLight> base_lights_;  // as loaded (their intensity and cones)
  Camera base_camera_;
  Sun base_sun_;  // as loaded: its radiance, which a moving sun fades at the horizon
  std::vector<SceneTriangle> previous_;
  std::vector<glm::mat4> previous_matrices_;  // the instances' last frame (Scene::instancing)
  std::vector<SceneTriangle> world_;          // with instances: the world's triangles posed
  FlatBvh bvh_;                               // the world tree on the devices, refitted from frame to frame
  double built_sah_ = 0.0;                    // its SAH cost when it was built
};

}  // namespace px
