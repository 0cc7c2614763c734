// The binary tree collapsed into 4- or 8-wide nodes (types.h: Bvh4Node, Bvh8Node), and the node
// buffers the kernels read for the wide layouts (wide_bvh.cpp).
#pragma once

#include "bvh/bvh_layout.h"
#include "bvh/flat_bvh.h"

#include <cstdint>
#include <vector>

namespace px {

// Fills bvh.nodes4 (width 4) or bvh.nodes8 (width 8) from the binary nodes: every wide node is
// a binary node whose children are replaced, largest surface area first, by their own
// children until it has `width` of them or only leaves. Returns the time taken in ms.
double collapse_bvh(FlatBvh& bvh, int width);

// The node buffer the kernels read for a wide layout (Wide4, Wide8, Compressed8): the wide
// nodes followed by one BvhLeafBlock per leaf (types.h), leaf slots pointing at their blocks
// (Wide4 / Wide8: the blocks in leaf order, that of their first triangle).
// Reads the triangles' flags, so call it after set_triangle_flags. Throws if the wide nodes are
// absent.
std::vector<std::uint32_t> device_wide_nodes(const FlatBvh& bvh, BvhLayout layout);
// device_wide_nodes for Wide4 and Wide8, the same words, made from nodes it frees on the way:
// the leaf blocks first, then the nodes (every word written once, none zero-filled first), each
// node's pages handed back once copied. At 10M triangles the nodes and the words are then never
// held whole side by side. With `refs`, the leaf triangles are moved out of `bvh` and become
// BvhLeafRef records as their blocks are written (kernels built with PX_LEAF_REFS read those).
// Throws std::invalid_argument for another layout or absent nodes.
DeviceWords device_wide_nodes_from(FlatBvh& bvh, BvhLayout layout, LeafRefs* refs = nullptr);
// The leaf block (types.h: BvhLeafBlock) of the `count` triangles from `first`; throws if they
// are out of range or count is not 1..4.
BvhLeafBlock leaf_block(const std::vector<BvhTriangle>& tris, std::uint32_t first, std::uint32_t count);

// Whether `bvh` carries the nodes of `layout` (the binary nodes always).
bool has_layout(const FlatBvh& bvh, BvhLayout layout);
// Makes sure `bvh` carries the nodes of `layout` (collapsing / compressing if needed). Returns
// the time that took in ms (0 when they were there).
double ensure_layout(FlatBvh& bvh, BvhLayout layout);

}  // namespace px
