#include "scene/scene_rig.h"

#include "scene/primitives.h"
#include "util/parallel_parts.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>

namespace px {

RigPrimitive cube_primitive(float half) {
  RigPrimitive cube;
  for (int i = 0; i < 8; ++i)
    cube.positions.push_back(glm::vec3((i & 1) ? half : -half, (i & 2) ? half : -half, (i & 4) ? half : -half));
  cube.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                    {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return cube;
}

int add_rig_node(SceneRig& rig, const RigNode& node, int primitive) {
  const int index = static_cast<int>(rig.nodes.size());
  rig.nodes.push_back(node);
  rig.order.push_back(index);
  RigMeshInstance inst;
  inst.node = index;
  inst.primitives = {primitive};
  std::vector<std::uint32_t> all(rig.primitives.at(static_cast<std::size_t>(primitive)).triangles.size());
  for (std::size_t t = 0; t < all.size(); ++t) all[t] = static_cast<std::uint32_t>(t);
  inst.kept = {all};
  rig.instances.push_back(inst);
  rig.triangle_count += all.size();
  return index;
}

Scene rig_scene(std::shared_ptr<const SceneRig> rig, const std::string& name) {
  Scene scene;
  scene.name = name;
  scene.materials.push_back(Material{});
  scene.sky.enabled = true;
  scene.sky.zenith = scene.sky.horizon = glm::vec3(1.0f);
  pose_rig(*rig, 0.0, {}, scene.triangles);
  scene.rig = std::move(rig);
  return scene;
}

glm::dmat4 trs_matrix(const glm::dvec3& t, const glm::dquat& r, const glm::dvec3& s) {
  glm::dmat4 m = glm::mat4_cast(r);
  m[0] *= s.x;
  m[1] *= s.y;
  m[2] *= s.z;
  m[3] = glm::dvec4(t, 1.0);
  return m;
}

std::vector<glm::dmat4> rig_world_matrices(const SceneRig& rig, double t, const std::vector<int>& clips) {
  // Each node's translation, rotation and scale: the rest values, replaced by the channels that
  // drive them (a later clip's channel wins where two drive the same property).
  struct Trs {
    glm::dvec3 t;
    glm::dquat r;
    glm::dvec3 s;
  };
  std::vector<Trs> trs(rig.nodes.size());
  for (std::size_t i = 0; i < rig.nodes.size(); ++i)
    trs[i] = {rig.nodes[i].translation, rig.nodes[i].rotation, rig.nodes[i].scale};
  for (int c : clips) {
    const AnimationClip& clip = rig.clips.at(static_cast<std::size_t>(c));
    const double ct = clip_time(clip, t);
    for (const AnimationChannel& ch : clip.channels) {
      if (ch.node < 0 || static_cast<std::size_t>(ch.node) >= rig.nodes.size()) continue;
      Trs& n = trs[static_cast<std::size_t>(ch.node)];
      const glm::dvec4 v = sample_track(ch.track, ct, ch.path == TrsPath::Rotation);
      switch (ch.path) {
        case TrsPath::Translation: n.t = glm::dvec3(v); break;
        case TrsPath::Rotation: n.r = glm::dquat(v.w, v.x, v.y, v.z); break;
        case TrsPath::Scale: n.s = glm::dvec3(v); break;
      }
    }
  }
  std::vector<glm::dmat4> world(rig.nodes.size(), glm::dmat4(1.0));
  for (int i : rig.order) {
    const RigNode& n = rig.nodes[static_cast<std::size_t>(i)];
    const Trs& p = trs[static_cast<std::size_t>(i)];
    const glm::dmat4 local = n.has_matrix ? n.matrix : trs_matrix(p.t, p.r, p.s);
    world[static_cast<std::size_t>(i)] = n.parent >= 0 ? world[static_cast<std::size_t>(n.parent)] * local : local;
  }
  return world;
}

std::vector<glm::dmat4> skin_matrices(const RigSkin& skin, const std::vector<glm::dmat4>& world) {
  std::vector<glm::dmat4> out(skin.joints.size());
  for (std::size_t j = 0; j < skin.joints.size(); ++j)
    out[j] = world.at(static_cast<std::size_t>(skin.joints[j])) * skin.inverse_bind[j];
  return out;
}

namespace {

bool finite3(const glm::vec3& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }

// The skinning matrix of vertex v: its joints' matrices blended by its weights (normalised; a
// vertex without weight stays in bind space).
glm::dmat4 vertex_skin(const RigPrimitive& prim, std::size_t v, const std::vector<glm::dmat4>& joints) {
  const glm::vec4 w = prim.weights[v];
  const double sum = double(w.x) + double(w.y) + double(w.z) + double(w.w);
  if (!(sum > 0.0) || !std::isfinite(sum)) return glm::dmat4(1.0);
  glm::dmat4 m(0.0);
  for (int k = 0; k < 4; ++k) {
    if (!(w[k] > 0.0f)) continue;
    const std::size_t j = static_cast<std::size_t>(prim.joints[v][k]);
    if (j >= joints.size()) continue;  // checked at load; a joint beyond the skin has no say
    m += (double(w[k]) / sum) * joints[j];
  }
  return m;
}

// From this many triangles a primitive's triangles are made on every core (parallel_parts).
constexpr std::size_t kEmitInPartsFrom = std::size_t{1} << 18;

}  // namespace

// emit_primitive, and emit_last_copy with `in_place` (= &prim): the vertices' world positions,
// normals and uvs are then written over prim's own (each read before it is written), not beside
// them; the triangles are the same.
static void emit_vertices_and_triangles(const RigPrimitive& prim, RigPrimitive* in_place, const glm::dmat4& world,
                                        const std::vector<glm::dmat4>* joint_matrices,
                                        const std::vector<std::uint32_t>* kept, std::vector<std::uint32_t>* record,
                                        std::vector<SceneTriangle>& out, SceneStats& stats,
                                        std::vector<std::array<glm::vec3, 3>>* colours) {
  const bool skinned = joint_matrices && !prim.joints.empty();
  std::vector<glm::vec3> pos_beside, normal_beside;
  std::vector<glm::vec2> uv_beside;
  if (!in_place) {
    pos_beside.resize(prim.positions.size());
    normal_beside.resize(prim.normals.size());
    uv_beside.resize(prim.uvs.size());
  }
  // Positions (and for skins each vertex's normal matrix) once per vertex.
  std::vector<glm::vec3>& world_pos = in_place ? in_place->positions : pos_beside;
  std::vector<glm::dmat3> vertex_normal_matrix;
  std::vector<char> vertex_flips;
  const glm::dmat3 linear(world);
  const glm::dmat3 normal_matrix = glm::transpose(glm::inverse(linear));
  // A mirroring transform turns the winding around; the front face must stay the front.
  const bool flip = glm::determinant(linear) < 0.0;
  if (skinned) {
    vertex_normal_matrix.resize(prim.positions.size());
    vertex_flips.resize(prim.positions.size());
    for (std::size_t v = 0; v < prim.positions.size(); ++v) {
      const glm::dmat4 m = vertex_skin(prim, v, *joint_matrices);
      world_pos[v] = glm::vec3(m * glm::dvec4(glm::dvec3(prim.positions[v]), 1.0));
      const glm::dmat3 l(m);
      vertex_normal_matrix[v] = glm::transpose(glm::inverse(l));
      vertex_flips[v] = glm::determinant(l) < 0.0;
    }
  } else {
    for (std::size_t v = 0; v < prim.positions.size(); ++v)
      world_pos[v] = glm::vec3(world * glm::dvec4(glm::dvec3(prim.positions[v]), 1.0));
  }
  // Normals and uvs once per vertex as well, not once per corner (a heightfield's vertex is a
  // corner of six triangles). A normal that degenerates is marked invalid: its corners take the
  // triangle's geometric normal.
  std::vector<glm::vec3>& world_normal = in_place ? in_place->normals : normal_beside;
  std::vector<char> normal_valid(prim.normals.size());
  for (std::size_t v = 0; v < prim.normals.size(); ++v) {
    const glm::dmat3& nm = skinned ? vertex_normal_matrix[v] : normal_matrix;
    const glm::vec3 wn(nm * glm::dvec3(prim.normals[v]));
    const float len = glm::length(wn);
    normal_valid[v] = len > 0.0f && std::isfinite(len);
    if (normal_valid[v]) world_normal[v] = wn / len;
  }
  std::vector<glm::vec2>& uvs = in_place ? in_place->uvs : uv_beside;
  for (std::size_t v = 0; v < prim.uvs.size(); ++v) {
    const glm::vec2& a = prim.uvs[v];
    // glTF's v runs down the image, the renderer's (OBJ's) up.
    uvs[v] = std::isfinite(a.x) && std::isfinite(a.y) ? glm::vec2(a.x, 1.0f - a.y) : glm::vec2(0.0f);
  }
  const std::size_t count = kept ? kept->size() : prim.triangles.size();
  // Triangle k's corners (in the order the front face needs) and positions into `tri`; whether
  // it stays, and then its geometric normal into *ng (null: the caller knows it stays, and the
  // normal is made only where a corner needs it, by attributes).
  enum Fate : std::uint8_t { kStays, kNonFinite, kDegenerate };
  const auto corners = [&](std::size_t k, SceneTriangle& tri, std::uint32_t(&order)[3], glm::vec3* ng) {
    const std::uint32_t ti = kept ? (*kept)[k] : static_cast<std::uint32_t>(k);
    const auto& t = prim.triangles[ti];
    const bool f = skinned ? vertex_flips[t[0]] != 0 : flip;
    order[0] = t[0];
    order[1] = f ? t[2] : t[1];
    order[2] = f ? t[1] : t[2];
    bool finite = true;
    for (int c = 0; c < 3; ++c) {
      tri.p[c] = world_pos[order[c]];
      finite &= finite3(tri.p[c]);
    }
    // A kept triangle stays, whatever this pose did to it: the triangle order is fixed.
    if (kept && !finite) tri.p[0] = tri.p[1] = tri.p[2] = glm::vec3(0.0f);
    if (kept || !ng) return kStays;
    if (!finite) return kNonFinite;
    if (!normal_unless_degenerate(tri, ng)) return kDegenerate;
    return *ng == glm::vec3(0.0f) ? kNonFinite : kStays;
  };
  // The geometric normal of a triangle that stays (corners' positions in `tri`): a kept one may
  // be degenerate or collapsed, and then faces +z.
  const auto normal_of = [&](const SceneTriangle& tri) {
    glm::vec3 ng(0.0f);
    normal_unless_degenerate(tri, &ng);
    if (kept && (!finite3(ng) || ng == glm::vec3(0.0f))) ng = glm::vec3(0.0f, 0.0f, 1.0f);
    return ng;
  };
  // The rest of a triangle that stays: its corners' normals (the geometric normal where a vertex
  // has none that holds: `ng` if known, else made here) and uvs, its material.
  const auto attributes = [&](const std::uint32_t(&order)[3], const glm::vec3* ng, SceneTriangle& tri) {
    tri.material = prim.material;
    glm::vec3 geometric(0.0f);
    bool have = false;
    for (int c = 0; c < 3; ++c) {
      if (!prim.normals.empty() && normal_valid[order[c]]) {
        tri.n[c] = world_normal[order[c]];
      } else {
        if (!have) geometric = ng ? *ng : normal_of(tri);
        have = true;
        tri.n[c] = geometric;
      }
      tri.uv[c] = prim.uvs.empty() ? glm::vec2(0.0f) : uvs[order[c]];
    }
  };
  const auto colours_of = [&](const std::uint32_t(&order)[3]) {
    std::array<glm::vec3, 3> rgb{glm::vec3(1.0f), glm::vec3(1.0f), glm::vec3(1.0f)};
    if (!prim.colours.empty())
      for (int c = 0; c < 3; ++c) rgb[std::size_t(c)] = prim.colours[order[c]];
    return rgb;
  };
  const auto count_fate = [&stats](Fate fate) {
    if (fate == kNonFinite) ++stats.dropped_nonfinite;
    if (fate == kDegenerate) ++stats.dropped_degenerate;
  };
  const unsigned parts = record ? 1u : parallel_parts(count, kEmitInPartsFrom);
  if (parts <= 1) {
    for (std::size_t k = 0; k < count; ++k) {
      SceneTriangle tri;
      std::uint32_t order[3];
      glm::vec3 ng(0.0f);
      const Fate fate = corners(k, tri, order, &ng);
      count_fate(fate);
      if (fate != kStays) continue;
      if (record) record->push_back(kept ? (*kept)[k] : static_cast<std::uint32_t>(k));
      attributes(order, kept ? nullptr : &ng, tri);
      out.push_back(tri);
      if (colours) colours->push_back(colours_of(order));
    }
    return;
  }
  // A large primitive on every core (a paper-size mesh's 100-byte triangles took a third of a
  // second on one): the same triangles in the same order. First which stay, part by part; then
  // the room for them (its fresh pages faulted in by the parts); then each part writes its own.
  std::vector<std::uint8_t> fates(kept ? 0 : count);
  std::vector<std::size_t> first_out(parts + 1, 0);
  if (kept) {
    for (unsigned part = 0; part <= parts; ++part) first_out[part] = count * part / parts;
  } else {
    std::vector<std::array<std::size_t, 3>> tally(parts, {0, 0, 0});
    run_parts(parts, [&](unsigned part) {
      const auto [begin, end] = part_range(count, part, parts);
      std::array<std::size_t, 3> mine{0, 0, 0};  // counted here: parts' tallies share a cache line
      for (std::size_t k = begin; k < end; ++k) {
        SceneTriangle tri;
        std::uint32_t order[3];
        glm::vec3 ng(0.0f);
        fates[k] = corners(k, tri, order, &ng);
        ++mine[fates[k]];
      }
      tally[part] = mine;
    });
    for (unsigned part = 0; part < parts; ++part) {
      first_out[part + 1] = first_out[part] + tally[part][kStays];
      stats.dropped_nonfinite += tally[part][kNonFinite];
      stats.dropped_degenerate += tally[part][kDegenerate];
    }
  }
  const std::size_t base = out.size(), colour_base = colours ? colours->size() : 0, made = first_out[parts];
  out.reserve(base + made);
  if (colours) colours->reserve(colour_base + made);
  run_parts(parts, [&](unsigned part) {
    populate_for_writing(out.data() + base + first_out[part], first_out[part + 1] - first_out[part]);
    if (colours)
      populate_for_writing(colours->data() + colour_base + first_out[part], first_out[part + 1] - first_out[part]);
  });
  out.resize(base + made);
  if (colours) colours->resize(colour_base + made);
  run_parts(parts, [&](unsigned part) {
    const auto [begin, end] = part_range(count, part, parts);
    std::size_t at = first_out[part];
    for (std::size_t k = begin; k < end; ++k) {
      if (!kept && fates[k] != kStays) continue;
      SceneTriangle& tri = out[base + at];
      std::uint32_t order[3];
      corners(k, tri, order, nullptr);
      attributes(order, nullptr, tri);
      if (colours) (*colours)[colour_base + at] = colours_of(order);
      ++at;
    }
  });
}

void emit_primitive(const RigPrimitive& prim, const glm::dmat4& world, const std::vector<glm::dmat4>* joint_matrices,
                    const std::vector<std::uint32_t>* kept, std::vector<std::uint32_t>* record,
                    std::vector<SceneTriangle>& out, SceneStats& stats,
                    std::vector<std::array<glm::vec3, 3>>* colours) {
  emit_vertices_and_triangles(prim, nullptr, world, joint_matrices, kept, record, out, stats, colours);
}

void emit_last_copy(RigPrimitive& prim, const glm::dmat4& world, std::vector<SceneTriangle>& out, SceneStats& stats,
                    std::vector<std::array<glm::vec3, 3>>* colours) {
  emit_vertices_and_triangles(prim, &prim, world, nullptr, nullptr, nullptr, out, stats, colours);
}

namespace {

// Every instance's triangles at the world matrices `world`: the kept ones (record == null), or,
// at load, all but the degenerate ones, whose indices go to (*record)[instance][primitive].
void emit_rig(const SceneRig& rig, const std::vector<glm::dmat4>& world,
              std::vector<std::vector<std::vector<std::uint32_t>>>* record, std::vector<SceneTriangle>& out,
              SceneStats& stats, std::vector<std::array<glm::vec3, 3>>* colours) {
  std::vector<std::vector<glm::dmat4>> joints(rig.skins.size());
  for (std::size_t s = 0; s < rig.skins.size(); ++s) joints[s] = skin_matrices(rig.skins[s], world);
  for (std::size_t i = 0; i < rig.instances.size(); ++i) {
    const RigMeshInstance& inst = rig.instances[i];
    if (inst.instance >= 0) continue;  // an instance: placed by its matrix (rig_instance_matrices)
    const glm::dmat4& w = world.at(static_cast<std::size_t>(inst.node));
    const std::vector<glm::dmat4>* jm = inst.skin >= 0 ? &joints[static_cast<std::size_t>(inst.skin)] : nullptr;
    for (std::size_t p = 0; p < inst.primitives.size(); ++p)
      emit_primitive(rig.primitives[static_cast<std::size_t>(inst.primitives[p])], w, jm,
                     record ? nullptr : &inst.kept[p], record ? &(*record)[i][p] : nullptr, out, stats, colours);
  }
}

}  // namespace

void pose_rig(const SceneRig& rig, double t, const std::vector<int>& clips, std::vector<SceneTriangle>& out) {
  pose_rig(rig, rig_world_matrices(rig, t, clips), out);
}

void pose_rig(const SceneRig& rig, const std::vector<glm::dmat4>& world, std::vector<SceneTriangle>& out) {
  out.clear();
  out.reserve(rig.triangle_count);
  SceneStats unused;
  emit_rig(rig, world, nullptr, out, unused, nullptr);
}

void settle_rig(SceneRig& rig, std::vector<SceneTriangle>& out, SceneStats& stats,
                std::vector<std::array<glm::vec3, 3>>* colours) {
  std::vector<std::vector<std::vector<std::uint32_t>>> kept(rig.instances.size());
  for (std::size_t i = 0; i < rig.instances.size(); ++i) kept[i].resize(rig.instances[i].primitives.size());
  const std::size_t first = out.size();
  emit_rig(rig, rig_world_matrices(rig, 0.0, {}), &kept, out, stats, colours);
  for (std::size_t i = 0; i < rig.instances.size(); ++i) rig.instances[i].kept = std::move(kept[i]);
  rig.triangle_count = out.size() - first;
}

void rig_instance_matrices(const SceneRig& rig, const std::vector<glm::dmat4>& world, SceneInstancing& instancing) {
  for (const RigMeshInstance& inst : rig.instances)
    if (inst.instance >= 0)
      instancing.instances.at(static_cast<std::size_t>(inst.instance)).object_to_world =
          glm::mat4(world.at(static_cast<std::size_t>(inst.node)));
}

std::vector<char> moving_nodes(const SceneRig& rig, const std::vector<int>& clips) {
  std::vector<char> moves(rig.nodes.size(), 0);
  for (int c : clips)
    for (const AnimationChannel& ch : rig.clips.at(static_cast<std::size_t>(c)).channels)
      if (ch.node >= 0 && static_cast<std::size_t>(ch.node) < moves.size())
        moves[static_cast<std::size_t>(ch.node)] = 1;
  // rig.order lists each node after its parent: one pass hands motion down the hierarchy.
  for (int n : rig.order) {
    const int parent = rig.nodes[static_cast<std::size_t>(n)].parent;
    if (parent >= 0 && moves[static_cast<std::size_t>(parent)]) moves[static_cast<std::size_t>(n)] = 1;
  }
  return moves;
}

void settle_rig_instances(SceneRig& rig, std::vector<SceneTriangle>& out, SceneStats& stats,
                          std::vector<std::array<glm::vec3, 3>>* colours, SceneInstancing& instancing) {
  instancing = SceneInstancing{};
  instancing.world_triangles = out.size();
  const std::vector<glm::dmat4> world = rig_world_matrices(rig, 0.0, {});
  std::vector<std::pair<std::vector<int>, std::uint32_t>> stored;  // primitives -> mesh slot
  int next = 0;
  for (RigMeshInstance& inst : rig.instances) {
    if (inst.instance < 0) continue;
    std::uint32_t slot = 0;
    bool found = false;
    for (const auto& [prims, k] : stored)
      if (prims == inst.primitives) slot = k, found = true;
    if (!found) {
      InstancedMesh mesh;
      mesh.first = out.size();
      inst.kept.assign(inst.primitives.size(), {});
      for (std::size_t p = 0; p < inst.primitives.size(); ++p)
        emit_primitive(rig.primitives[static_cast<std::size_t>(inst.primitives[p])], glm::dmat4(1.0), nullptr, nullptr,
                       &inst.kept[p], out, stats, colours);
      mesh.count = out.size() - mesh.first;
      if (mesh.count == 0) {  // nothing drawable: posed with the world's (none) instead
        inst.instance = -1;
        continue;
      }
      slot = static_cast<std::uint32_t>(instancing.meshes.size());
      instancing.meshes.push_back(mesh);
      stored.emplace_back(inst.primitives, slot);
    }
    inst.instance = next++;
    MeshInstance m;
    m.mesh = slot;
    m.object_to_world = glm::mat4(world.at(static_cast<std::size_t>(inst.node)));
    instancing.instances.push_back(m);
  }
  if (instancing.instances.empty()) instancing = SceneInstancing{};
}

bool camera_from_node(const glm::dmat4& world, Camera& cam) {
  const glm::dvec3 pos(world * glm::dvec4(0, 0, 0, 1));
  const glm::dvec3 fwd(world * glm::dvec4(0, 0, -1, 0));
  const glm::dvec3 up(world * glm::dvec4(0, 1, 0, 0));
  const double fl = glm::length(fwd);
  if (!(fl > 0.0) || !(glm::length(glm::cross(fwd, up)) > 0.0)) return false;
  cam.position = glm::vec3(pos);
  cam.target = glm::vec3(pos + fwd / fl);
  cam.up = glm::vec3(glm::normalize(up));
  return true;
}

Camera rig_camera(const SceneRig& rig, const std::vector<glm::dmat4>& world, const Camera& base) {
  Camera c = base;
  if (rig.camera_node >= 0) camera_from_node(world.at(static_cast<std::size_t>(rig.camera_node)), c);
  return c;
}

bool rig_moves(const SceneRig& rig, const std::vector<int>& clips) {
  for (int c : clips)
    if (!rig.clips.at(static_cast<std::size_t>(c)).channels.empty()) return true;
  return false;
}

}  // namespace px
