// Embree's builder callbacks: the nodes and leaves of the tree rtcBuildBVH makes, in Embree's
// thread-local allocator.
#include "bvh/embree_build_tree.h"

#include <algorithm>
#include <new>

namespace px::embree_build {

void* create_node(RTCThreadLocalAllocator allocator, unsigned int child_count, void* user) {
  auto* context = static_cast<BuildContext*>(user);
  if (child_count != 2) context->unexpected_arity = true;
  void* memory = rtcThreadLocalAlloc(allocator, sizeof(TempInner), alignof(TempInner));
  if (!memory) {
    context->out_of_memory = true;
    return nullptr;
  }
  auto* node = new (memory) TempInner;
  node->is_leaf = false;
  node->child[0] = node->child[1] = nullptr;
  node->height = 0;
  node->leaf_count = 0;
  return node;
}

void set_node_children(void* node_ptr, void** children, unsigned int child_count, void*) {
  auto* node = static_cast<TempInner*>(node_ptr);
  if (!node) return;
  for (unsigned int i = 0; i < std::min(child_count, 2u); ++i) node->child[i] = static_cast<TempNode*>(children[i]);
}

void set_node_bounds(void* node_ptr, const RTCBounds** bounds, unsigned int child_count, void*) {
  auto* node = static_cast<TempInner*>(node_ptr);
  if (!node) return;
  for (unsigned int i = 0; i < std::min(child_count, 2u); ++i) node->bounds[i] = *bounds[i];
}

void* create_leaf(RTCThreadLocalAllocator allocator, const RTCBuildPrimitive* primitives, size_t primitive_count,
                  void* user) {
  auto* context = static_cast<BuildContext*>(user);
  void* memory = rtcThreadLocalAlloc(allocator, sizeof(TempLeaf), alignof(TempLeaf));
  if (!memory) {
    context->out_of_memory = true;
    return nullptr;
  }
  auto* leaf = new (memory) TempLeaf;
  leaf->is_leaf = true;
  leaf->count = 0;
  for (size_t i = 0; i < primitive_count; ++i) {
    // With spatial splits two fragments of one triangle can land in the same leaf; the leaf
    // box already covers both, so one reference is enough and saves an intersection.
    const std::uint32_t prim = primitives[i].primID;
    if (std::find(leaf->prims, leaf->prims + leaf->count, prim) != leaf->prims + leaf->count) continue;
    if (leaf->count == PX_BVH_MAX_LEAF_SIZE) {
      context->oversized_leaf = true;
      break;
    }
    leaf->prims[leaf->count++] = prim;
  }
  return leaf;
}

}  // namespace px::embree_build
