// flatten_tree(): Embree's tree copied into the flat binary nodes, subtrees that would end too
// deep rebuilt as balanced trees over their leaves.
#include "bvh/bvh_flattener.h"

#include <algorithm>
#include <limits>
#include <stdexcept>

namespace px::embree_build {

namespace {

int ceil_log2(std::size_t n) {
  int bits = 0;
  while ((std::size_t{1} << bits) < n) ++bits;
  return bits;
}

// Heights and leaf counts of every inner node (single-threaded, after the build).
void annotate(TempNode* node) {
  if (node->is_leaf) return;
  auto* inner = static_cast<TempInner*>(node);
  inner->height = 1;
  inner->leaf_count = 0;
  for (TempNode* child : inner->child) {
    if (child->is_leaf) {
      inner->leaf_count += 1;
    } else {
      annotate(child);
      const auto* c = static_cast<const TempInner*>(child);
      inner->height = std::max(inner->height, c->height + 1);
      inner->leaf_count += c->leaf_count;
    }
  }
}

class Flattener {
 public:
  // Writes the nodes to out.nodes and the leaves' scene triangle indices, in leaf order, to
  // `leaf_prims` (leaf_triangles makes the BvhTriangles of them once Embree's tree is gone).
  Flattener(const TriangleSource& scene, FlatBvh& out, std::vector<std::uint32_t>& leaf_prims, int max_depth)
      : scene_(scene), out_(out), leaf_prims_(leaf_prims), max_depth_(max_depth) {}

  void flatten(TempNode* root) {
    if (root->is_leaf) {
      // The whole scene fits one leaf: the root node's left child is that leaf and its right
      // child is absent (inverted box, never entered).
      const auto* leaf = static_cast<const TempLeaf*>(root);
      RTCBounds box;
      set_empty(&box);
      for (std::uint32_t i = 0; i < leaf->count; ++i) extend(box, scene_.p(leaf->prims[i]));
      out_.nodes.emplace_back();
      set_child(0, 0, box, emit_leaf(leaf), leaf->count);
      constexpr float kMax = std::numeric_limits<float>::max();
      const RTCBounds absent = {kMax, kMax, kMax, 0.0f, -kMax, -kMax, -kMax, 0.0f};
      set_child(0, 1, absent, 0, 0);
      return;
    }
    auto* inner = static_cast<TempInner*>(root);
    annotate(inner);
    if (1 + ceil_log2(inner->leaf_count) > max_depth_)
      throw std::runtime_error("BVH: too many leaves for the depth limit");
    emit(inner, 1);
  }

 private:
  struct LeafItem {
    const TempLeaf* leaf;
    RTCBounds box;
    float centroid[3];
  };

  static void extend(RTCBounds& box, const glm::vec3* corners) {
    for (int c = 0; c < 3; ++c) {
      const glm::vec3& p = corners[c];
      box.lower_x = std::min(box.lower_x, p.x), box.upper_x = std::max(box.upper_x, p.x);
      box.lower_y = std::min(box.lower_y, p.y), box.upper_y = std::max(box.upper_y, p.y);
      box.lower_z = std::min(box.lower_z, p.z), box.upper_z = std::max(box.upper_z, p.z);
    }
  }

  void set_child(std::uint32_t node_index, int side, const RTCBounds& box, std::uint32_t index, std::uint32_t count) {
    BvhNode& node = out_.nodes[node_index];
    float* lo = side == 0 ? node.lmin : node.rmin;
    float* hi = side == 0 ? node.lmax : node.rmax;
    lo[0] = box.lower_x, lo[1] = box.lower_y, lo[2] = box.lower_z;
    hi[0] = box.upper_x, hi[1] = box.upper_y, hi[2] = box.upper_z;
    (side == 0 ? node.left : node.right) = index;
    (side == 0 ? node.left_count : node.right_count) = count;
  }

  // Appends the leaf's triangles; returns the index of the first.
  std::uint32_t emit_leaf(const TempLeaf* leaf) {
    const auto first = static_cast<std::uint32_t>(leaf_prims_.size());
    leaf_prims_.insert(leaf_prims_.end(), leaf->prims, leaf->prims + leaf->count);
    return first;
  }

  // Writes `node` placed at `depth` (root = 1). Precondition: a balanced tree over its leaves
  // fits, depth + ceil_log2(leaf_count) <= max_depth_.
  std::uint32_t emit(const TempInner* node, int depth) {
    bool keep = depth + node->height <= max_depth_;
    if (!keep) {
      // Descend if both children can still be made to fit one level down; otherwise this is
      // the deepest place where a balanced rebuild fits.
      keep = true;
      for (const TempNode* child : node->child)
        if (!child->is_leaf && depth + 1 + ceil_log2(static_cast<const TempInner*>(child)->leaf_count) > max_depth_)
          keep = false;
      if (!keep) {
        std::vector<LeafItem> items;
        items.reserve(node->leaf_count);
        collect_leaves(node, items);
        return emit_balanced(items.data(), items.size(), depth);
      }
    }
    const auto index = static_cast<std::uint32_t>(out_.nodes.size());
    out_.nodes.emplace_back();
    for (int side = 0; side < 2; ++side) {
      const TempNode* child = node->child[side];
      if (child->is_leaf) {
        const auto* leaf = static_cast<const TempLeaf*>(child);
        set_child(index, side, node->bounds[side], emit_leaf(leaf), leaf->count);
      } else {
        // Depth-first: the left child's subtree follows its parent directly in memory.
        const std::uint32_t child_index = emit(static_cast<const TempInner*>(child), depth + 1);
        set_child(index, side, node->bounds[side], child_index, 0);
      }
    }
    return index;
  }

  void collect_leaves(const TempInner* node, std::vector<LeafItem>& items) {
    for (int side = 0; side < 2; ++side) {
      const TempNode* child = node->child[side];
      if (!child->is_leaf) {
        collect_leaves(static_cast<const TempInner*>(child), items);
        continue;
      }
      LeafItem item;
      item.leaf = static_cast<const TempLeaf*>(child);
      item.box = node->bounds[side];
      item.centroid[0] = 0.5f * (item.box.lower_x + item.box.upper_x);
      item.centroid[1] = 0.5f * (item.box.lower_y + item.box.upper_y);
      item.centroid[2] = 0.5f * (item.box.lower_z + item.box.upper_z);
      items.push_back(item);
    }
  }

  static RTCBounds merged(const LeafItem* items, std::size_t n) {
    RTCBounds box;
    set_empty(&box);
    for (std::size_t i = 0; i < n; ++i) {
      const RTCBounds& b = items[i].box;
      box.lower_x = std::min(box.lower_x, b.lower_x), box.upper_x = std::max(box.upper_x, b.upper_x);
      box.lower_y = std::min(box.lower_y, b.lower_y), box.upper_y = std::max(box.upper_y, b.upper_y);
      box.lower_z = std::min(box.lower_z, b.lower_z), box.upper_z = std::max(box.upper_z, b.upper_z);
    }
    return box;
  }

  // Balanced binary tree over n >= 2 leaves, split at the median centroid along the widest
  // centroid axis: leaves end at depth + ceil_log2(n).
  std::uint32_t emit_balanced(LeafItem* items, std::size_t n, int depth) {
    float cmin[3] = {kInf, kInf, kInf}, cmax[3] = {-kInf, -kInf, -kInf};
    for (std::size_t i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k) {
        cmin[k] = std::min(cmin[k], items[i].centroid[k]);
        cmax[k] = std::max(cmax[k], items[i].centroid[k]);
      }
    int axis = 0;
    for (int k = 1; k < 3; ++k)
      if (cmax[k] - cmin[k] > cmax[axis] - cmin[axis]) axis = k;
    const std::size_t half = (n + 1) / 2;
    std::nth_element(items, items + half, items + n,
                     [axis](const LeafItem& a, const LeafItem& b) { return a.centroid[axis] < b.centroid[axis]; });

    const auto index = static_cast<std::uint32_t>(out_.nodes.size());
    out_.nodes.emplace_back();
    const std::size_t begin[2] = {0, half};
    const std::size_t count[2] = {half, n - half};
    for (int side = 0; side < 2; ++side) {
      LeafItem* part = items + begin[side];
      if (count[side] == 1) {
        set_child(index, side, part->box, emit_leaf(part->leaf), part->leaf->count);
      } else {
        const std::uint32_t child = emit_balanced(part, count[side], depth + 1);
        set_child(index, side, merged(part, count[side]), child, 0);
      }
    }
    return index;
  }

  const TriangleSource& scene_;
  FlatBvh& out_;
  std::vector<std::uint32_t>& leaf_prims_;
  int max_depth_;
};

}  // namespace

void flatten_tree(const TriangleSource& scene, TempNode* root, FlatBvh& out, std::vector<std::uint32_t>& leaf_prims,
                  int max_depth) {
  Flattener(scene, out, leaf_prims, max_depth).flatten(root);
}

}  // namespace px::embree_build
