#include "bvh/top_level_bvh.h"

#include <algorithm>
#include <cfloat>
#include <cstring>
#include <functional>
#include <stdexcept>
#include <string>

namespace px {
namespace {

void set_box(float* lo, float* hi, const InstanceBox& b) {
  for (int a = 0; a < 3; ++a) {
    lo[a] = b.lo[a];
    hi[a] = b.hi[a];
  }
}

InstanceBox merge(const std::vector<InstanceBox>& boxes, const std::vector<std::uint32_t>& order, std::size_t first,
                  std::size_t count) {
  InstanceBox b{glm::vec3(FLT_MAX), glm::vec3(-FLT_MAX)};
  for (std::size_t i = first; i < first + count; ++i) {
    b.lo = glm::min(b.lo, boxes[order[i]].lo);
    b.hi = glm::max(b.hi, boxes[order[i]].hi);
  }
  return b;
}

void matrix_rows(float* out, const glm::dmat4& m) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) out[4 * r + c] = static_cast<float>(m[c][r]);
}

}  // namespace

InstanceBox place_box(const glm::vec3& lo, const glm::vec3& hi, const glm::mat4& m) {
  InstanceBox b{glm::vec3(FLT_MAX), glm::vec3(-FLT_MAX)};
  for (int k = 0; k < 8; ++k) {
    const glm::vec3 corner((k & 1) ? hi.x : lo.x, (k & 2) ? hi.y : lo.y, (k & 4) ? hi.z : lo.z);
    const glm::vec3 w = glm::vec3(m * glm::vec4(corner, 1.0f));
    b.lo = glm::min(b.lo, w);
    b.hi = glm::max(b.hi, w);
  }
  // The corners are rounded once each; widen by a few ulps so that the box holds the mesh as
  // the kernels transform it (rays are tested against the mesh in its own space, so a box only
  // has to be conservative, never exact).
  const glm::vec3 pad = (glm::abs(b.lo) + glm::abs(b.hi) + glm::vec3(1e-30f)) * (8.0f * FLT_EPSILON);
  b.lo -= pad;
  b.hi += pad;
  return b;
}

TopLevelBvh build_top_level(const std::vector<InstanceBox>& boxes) {
  TopLevelBvh out;
  if (boxes.empty()) return out;
  out.order.resize(boxes.size());
  for (std::size_t i = 0; i < boxes.size(); ++i) out.order[i] = static_cast<std::uint32_t>(i);
  out.nodes.reserve(boxes.size());
  // Builds the node for instances [first, first + count) (count > PX_TLAS_MAX_LEAF, or the
  // root) and returns its index.
  std::function<std::uint32_t(std::size_t, std::size_t, int)> build = [&](std::size_t first, std::size_t count,
                                                                          int depth) -> std::uint32_t {
    out.depth = std::max(out.depth, depth);
    const std::uint32_t index = static_cast<std::uint32_t>(out.nodes.size());
    out.nodes.push_back(BvhNode{});
    std::size_t left_count = count / 2;
    if (count <= PX_TLAS_MAX_LEAF) {
      left_count = count;  // the root of a tiny scene: one leaf, the other child absent
    } else {
      glm::vec3 clo(FLT_MAX), chi(-FLT_MAX);
      for (std::size_t i = first; i < first + count; ++i) {
        const glm::vec3 c = 0.5f * (boxes[out.order[i]].lo + boxes[out.order[i]].hi);
        clo = glm::min(clo, c);
        chi = glm::max(chi, c);
      }
      const glm::vec3 ext = chi - clo;
      const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
      const auto begin = out.order.begin() + std::ptrdiff_t(first);
      std::nth_element(begin, begin + std::ptrdiff_t(left_count), begin + std::ptrdiff_t(count),
                       [&](std::uint32_t a, std::uint32_t b) {
                         const float ca = boxes[a].lo[axis] + boxes[a].hi[axis];
                         const float cb = boxes[b].lo[axis] + boxes[b].hi[axis];
                         return ca < cb || (ca == cb && a < b);
                       });
    }
    const std::size_t right_count = count - left_count;
    const InstanceBox lb = merge(boxes, out.order, first, left_count);
    std::uint32_t left = static_cast<std::uint32_t>(first), lcount = static_cast<std::uint32_t>(left_count);
    if (left_count > PX_TLAS_MAX_LEAF) {
      left = build(first, left_count, depth + 1);
      lcount = 0;
    }
    BvhNode n{};
    set_box(n.lmin, n.lmax, lb);
    n.left = left;
    n.left_count = lcount;
    if (right_count == 0) {
      const InstanceBox absent{glm::vec3(FLT_MAX), glm::vec3(-FLT_MAX)};
      set_box(n.rmin, n.rmax, absent);
      n.right = 0;
      n.right_count = 0;
    } else {
      const InstanceBox rb = merge(boxes, out.order, first + left_count, right_count);
      std::uint32_t right = static_cast<std::uint32_t>(first + left_count),
                    rcount = static_cast<std::uint32_t>(right_count);
      if (right_count > PX_TLAS_MAX_LEAF) {
        right = build(first + left_count, right_count, depth + 1);
        rcount = 0;
      }
      set_box(n.rmin, n.rmax, rb);
      n.right = right;
      n.right_count = rcount;
    }
    out.nodes[index] = n;
    return index;
  };
  build(0, boxes.size(), 1);
  if (out.depth > PX_TLAS_STACK_SIZE)
    throw std::logic_error("top-level BVH deeper than its traversal stack (" + std::to_string(out.depth) + ")");
  return out;
}

std::vector<std::uint32_t> instance_buffer_words(const Scene& scene, const std::vector<MeshPlacement>& meshes,
                                                 std::size_t world_triangles, TopLevelBvh* top_out,
                                                 const std::vector<glm::mat4>* previous) {
  const SceneInstancing& in = scene.instancing;
  SceneInstances header{};
  header.world_triangles = static_cast<std::uint32_t>(std::min<std::size_t>(world_triangles, 0xffffffffu));
  if (in.empty()) {
    std::vector<std::uint32_t> words(sizeof header / 4);
    std::memcpy(words.data(), &header, sizeof header);
    return words;
  }
  if (meshes.size() != in.meshes.size())
    throw std::logic_error("instance_buffer_words: " + std::to_string(meshes.size()) + " placements for " +
                           std::to_string(in.meshes.size()) + " meshes");
  // Each mesh's own box, then each instance's world box.
  std::vector<InstanceBox> mesh_box(in.meshes.size(), InstanceBox{glm::vec3(FLT_MAX), glm::vec3(-FLT_MAX)});
  for (std::size_t k = 0; k < in.meshes.size(); ++k)
    for (std::size_t i = in.meshes[k].first; i < in.meshes[k].first + in.meshes[k].count; ++i)
      for (const glm::vec3& p : scene.triangles[i].p) {
        mesh_box[k].lo = glm::min(mesh_box[k].lo, p);
        mesh_box[k].hi = glm::max(mesh_box[k].hi, p);
      }
  std::vector<InstanceBox> boxes(in.instances.size());
  for (std::size_t i = 0; i < boxes.size(); ++i) {
    const MeshInstance& inst = in.instances[i];
    boxes[i] = place_box(mesh_box[inst.mesh].lo, mesh_box[inst.mesh].hi, inst.object_to_world);
  }
  TopLevelBvh top = build_top_level(boxes);
  header.count = static_cast<std::uint32_t>(in.instances.size());
  header.nodes = static_cast<std::uint32_t>(top.nodes.size());
  const std::size_t order_at = sizeof header + top.nodes.size() * sizeof(BvhNode);  // 16-byte aligned
  header.order = static_cast<std::uint32_t>(order_at / 16);
  header.records = static_cast<std::uint32_t>((order_at + top.order.size() * 4 + 15) / 16);
  std::vector<std::uint32_t> words((header.records * std::size_t(16) + in.instances.size() * sizeof(SceneInstance)) /
                                   4);
  auto* bytes = reinterpret_cast<std::uint8_t*>(words.data());
  std::memcpy(bytes, &header, sizeof header);
  std::memcpy(bytes + sizeof header, top.nodes.data(), top.nodes.size() * sizeof(BvhNode));
  std::memcpy(bytes + order_at, top.order.data(), top.order.size() * 4);
  if (previous && previous->size() != in.instances.size())
    throw std::logic_error("instance_buffer_words: " + std::to_string(previous->size()) + " previous matrices for " +
                           std::to_string(in.instances.size()) + " instances");
  for (std::size_t i = 0; i < in.instances.size(); ++i) {
    const MeshInstance& inst = in.instances[i];
    SceneInstance rec{};
    const glm::dmat4 m(inst.object_to_world);
    matrix_rows(rec.object_to_world, m);
    matrix_rows(rec.world_to_object, glm::inverse(m));
    matrix_rows(rec.previous_object_to_world, previous ? glm::dmat4((*previous)[i]) : m);
    rec.node_offset = meshes[inst.mesh].node_offset;
    rec.triangle_offset = meshes[inst.mesh].triangle_offset;
    std::memcpy(bytes + std::size_t(header.records) * 16 + i * sizeof(SceneInstance), &rec, sizeof rec);
  }
  if (top_out) *top_out = std::move(top);
  return words;
}

}  // namespace px
