// What it takes to pose a glTF scene at any time: the node hierarchy with each node's rest
// transform, the meshes in their own (local) space, the skins and the animation clips. The
// loader keeps one in Scene::rig when the file's scene moves (animations); a static file is
// posed once at load and keeps none.
//
// A posed scene has the same triangles in the same order at every time (those kept at load:
// degenerate or non-finite ones at the rest pose are dropped once, for good), so that triangle i
// of one frame is triangle i of the next: the BVH is rebuilt over them every frame, and motion
// vectors (a point's position in the previous frame) are read by triangle index.
#pragma once

#include "scene/animation.h"
#include "scene/scene.h"

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include <array>
#include <memory>
#include <string>
#include <cstdint>
#include <vector>

namespace px {

struct RigNode {
  int parent = -1;
  // A node is given either by a matrix (never animated, glTF's rule) or by its translation,
  // rotation and scale, which channels replace.
  bool has_matrix = false;
  glm::dmat4 matrix{1.0};
  glm::dvec3 translation{0.0};
  glm::dquat rotation{1.0, 0.0, 0.0, 0.0};
  glm::dvec3 scale{1.0};
};

// One glTF mesh primitive as the file has it: local positions, optional normals and texture
// coordinates (glTF's v, running down the image), triangles in the file's winding, and for a
// skinned mesh four joints (indices into its skin's joint list) and weights per vertex.
struct RigPrimitive {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;  // empty: the geometric normal
  std::vector<glm::vec2> uvs;      // empty: zero
  std::vector<glm::vec3> colours;  // COLOR_0, linear RGB; empty: white
  std::vector<std::array<std::uint32_t, 3>> triangles;
  std::uint32_t material = 0;
  std::vector<glm::vec4> joints;  // empty: not skinned
  std::vector<glm::vec4> weights;
};

// A node's mesh: the node, its skin (-1: none; a skinned mesh ignores its node's transform, as
// glTF says) and its primitives, each with the triangles kept at load.
struct RigMeshInstance {
  int node = -1;
  int skin = -1;
  std::vector<int> primitives;                   // indices into SceneRig::primitives
  std::vector<std::vector<std::uint32_t>> kept;  // per primitive: its triangles kept, in order
  // Drawn as Scene::instancing's instance `instance` (its mesh stored once in its own space, its
  // node's world matrix placing it every frame), or -1: posed into the world's triangles.
  int instance = -1;
};

struct RigSkin {
  std::vector<int> joints;               // node indices
  std::vector<glm::dmat4> inverse_bind;  // one per joint (identity when the file gives none)
};

struct SceneRig {
  std::vector<RigNode> nodes;  // indexed as the file's nodes
  std::vector<int> order;      // the default scene's nodes, each after its parent
  std::vector<RigPrimitive> primitives;
  std::vector<RigMeshInstance> instances;  // in the order their triangles appear in Scene::triangles
  std::vector<RigSkin> skins;
  std::vector<AnimationClip> clips;
  int camera_node = -1;  // the node of the scene's camera (-1: not a glTF camera)
  int sun_node = -1;     // the node of the directional light that is the scene's sun (-1: none)
  // Per glTF point or spot light, in Scene::punctual_lights' order (lights a scene file adds after
  // them have none): its node, whose origin is the light's position and whose -z its direction.
  std::vector<int> light_nodes;
  std::size_t triangle_count = 0;
};

// Rigs made in code (benches, tests): a cube of half-size `half` about the origin, 12
// triangles facing out; and a node with its mesh instance appended to `rig` (a root, every
// triangle of `primitive` kept). Returns the node's index.
RigPrimitive cube_primitive(float half);
int add_rig_node(SceneRig& rig, const RigNode& node, int primitive);
// A scene around such a rig: one grey material, a uniform white sky, the triangles at rest.
Scene rig_scene(std::shared_ptr<const SceneRig> rig, const std::string& name);

// A node's transform from translation, rotation and scale (T * R * S).
glm::dmat4 trs_matrix(const glm::dvec3& t, const glm::dquat& r, const glm::dvec3& s);

// World matrices of every node (identity for nodes outside the default scene) at scene time
// `t` with clips `clips` playing (indices into rig.clips; none: the rest pose).
std::vector<glm::dmat4> rig_world_matrices(const SceneRig& rig, double t, const std::vector<int>& clips);

// Appends `prim`'s triangles in world space: through `world`, or, for a skinned primitive,
// through each vertex's blend of `joint_matrices` (joint world x inverse bind). A mirroring
// transform reverses the winding so that the front face stays the front.
//   kept == nullptr: degenerate and non-finite triangles are dropped (counted in `stats`) and the
//     indices of those emitted are appended to *record (if given);
//   kept != nullptr: exactly those triangles, in that order, whatever this pose makes of them
//     (a triangle non-finite here collapses to a point, which no ray hits).
// `colours` (if given) receives one entry per triangle emitted: its corners' vertex colours,
// white for a primitive without them.
void emit_primitive(const RigPrimitive& prim, const glm::dmat4& world, const std::vector<glm::dmat4>* joint_matrices,
                    const std::vector<std::uint32_t>* kept, std::vector<std::uint32_t>* record,
                    std::vector<SceneTriangle>& out, SceneStats& stats,
                    std::vector<std::array<glm::vec3, 3>>* colours = nullptr);
// emit_primitive (no skin, every triangle that is not dropped) for the last copy of a static
// mesh's primitive, which nothing reads afterwards: its own positions, normals and uvs are turned
// to world space in place instead of into arrays beside them, which stood at the load's highest
// point (docs/measurements.md, "What is resident at each highest point"). The same triangles.
void emit_last_copy(RigPrimitive& prim, const glm::dmat4& world, std::vector<SceneTriangle>& out, SceneStats& stats,
                    std::vector<std::array<glm::vec3, 3>>* colours = nullptr);

// The joint matrices of `skin` (joint world x inverse bind) from the world matrices.
std::vector<glm::dmat4> skin_matrices(const RigSkin& skin, const std::vector<glm::dmat4>& world);

// Every instance's kept triangles at time `t` with `clips` playing, in load order (`out` is
// overwritten; rig.triangle_count triangles). Mesh instances drawn as instances
// (RigMeshInstance::instance >= 0) are not among them: rig_instance_matrices places those.
void pose_rig(const SceneRig& rig, double t, const std::vector<int>& clips, std::vector<SceneTriangle>& out);
// The same at world matrices already evaluated (rig_world_matrices).
void pose_rig(const SceneRig& rig, const std::vector<glm::dmat4>& world, std::vector<SceneTriangle>& out);

// The world matrix of every mesh instance drawn as an instance, at these world matrices, into
// `instancing` (its instances' object_to_world, by RigMeshInstance::instance).
void rig_instance_matrices(const SceneRig& rig, const std::vector<glm::dmat4>& world, SceneInstancing& instancing);

// Which nodes a clip moves: a node any of `clips`' channels drives, or a descendant of one
// (indexed as rig.nodes; 1 = moves).
std::vector<char> moving_nodes(const SceneRig& rig, const std::vector<int>& clips);

// The loader's step after settle_rig for a rig with instances: the meshes of the mesh instances
// marked as instances (RigMeshInstance::instance), each stored once in its own space (mesh
// instances with the same primitives share it), appended to `out` (and `colours`), and
// `instancing` filled: world_triangles = the triangles before them, a mesh per stored mesh, the
// instances at the rest pose. Degenerate triangles are dropped in the mesh's space.
void settle_rig_instances(SceneRig& rig, std::vector<SceneTriangle>& out, SceneStats& stats,
                          std::vector<std::array<glm::vec3, 3>>* colours, SceneInstancing& instancing);

// The loader's last step: the rig at its rest pose appended to `out` (and `colours`, if given),
// dropping degenerate and non-finite triangles (counted in `stats`); what is kept becomes each
// instance's `kept` list and rig.triangle_count, for good.
void settle_rig(SceneRig& rig, std::vector<SceneTriangle>& out, SceneStats& stats,
                std::vector<std::array<glm::vec3, 3>>* colours);

// A glTF camera's view from its node's world matrix (the camera looks down its local -z, up
// its local +y) into `cam`'s position, target and up; false (cam untouched) when the matrix
// makes the view degenerate.
bool camera_from_node(const glm::dmat4& world, Camera& cam);

// The camera of `rig.camera_node` at these world matrices, keeping `base`'s field of view; base
// unchanged when the rig has no camera node (or its view degenerates there).
Camera rig_camera(const SceneRig& rig, const std::vector<glm::dmat4>& world, const Camera& base);

// Whether any of `clips` drives a node (so the scene's pose changes with time).
bool rig_moves(const SceneRig& rig, const std::vector<int>& clips);

}  // namespace px
