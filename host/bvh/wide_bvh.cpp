// collapse_bvh(): the binary tree of build_bvh collapsed into 4- or 8-wide nodes (layout in
// kernels/shared/types.h), and the node buffers the kernels read for the wide layouts.
#include "bvh/wide_bvh.h"

#include "bvh/compressed_bvh.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include <sys/mman.h>
#include <unistd.h>

namespace px {

namespace {

struct ChildRef {
  float lo[3], hi[3];
  std::uint32_t index;  // binary node, or first triangle of a leaf
  std::uint32_t count;  // 0 = interior
  double half_area() const {
    const double dx = double(hi[0]) - lo[0], dy = double(hi[1]) - lo[1], dz = double(hi[2]) - lo[2];
    return dx * dy + dy * dz + dz * dx;
  }
};

// The present children of binary node `n`, appended to `out`.
template <typename Out>
void binary_children(const BvhNode& n, Out& out, int& size) {
  const float* lo[2] = {n.lmin, n.rmin};
  const float* hi[2] = {n.lmax, n.rmax};
  const std::uint32_t index[2] = {n.left, n.right};
  const std::uint32_t count[2] = {n.left_count, n.right_count};
  for (int side = 0; side < 2; ++side) {
    if (is_absent_box(lo[side], hi[side])) continue;
    ChildRef& c = out[size++];
    for (int k = 0; k < 3; ++k) c.lo[k] = lo[side][k], c.hi[k] = hi[side][k];
    c.index = index[side];
    c.count = count[side];
  }
}

template <int W, typename Node>
class Collapser {
 public:
  Collapser(const FlatBvh& bvh, std::vector<Node>& out) : bvh_(bvh), out_(out) {}

  // Emits the wide node standing for binary node `b` (and its subtree); returns its index.
  std::uint32_t emit(std::uint32_t b) {
    ChildRef children[W];
    int size = 0;
    binary_children(bvh_.nodes[b], children, size);
    // Open the interior child with the largest surface area (the one rays enter most often)
    // until the node is full or holds only leaves.
    while (size < W) {
      int best = -1;
      double best_area = -1.0;
      for (int i = 0; i < size; ++i)
        if (children[i].count == 0 && children[i].half_area() > best_area) {
          best = i;
          best_area = children[i].half_area();
        }
      if (best < 0) break;
      const std::uint32_t opened = children[best].index;
      children[best] = children[--size];
      binary_children(bvh_.nodes[opened], children, size);
    }

    const auto index = static_cast<std::uint32_t>(out_.size());
    out_.emplace_back();
    for (int i = 0; i < W; ++i) {
      const bool used = i < size;
      // Depth-first: the first interior child's subtree follows its parent in memory.
      const std::uint32_t child = !used ? 0u : (children[i].count > 0 ? children[i].index : emit(children[i].index));
      Node& node = out_[index];  // emit() may have reallocated
      const float big = std::numeric_limits<float>::max();
      node.lo_x[i] = used ? children[i].lo[0] : big;
      node.lo_y[i] = used ? children[i].lo[1] : big;
      node.lo_z[i] = used ? children[i].lo[2] : big;
      node.hi_x[i] = used ? children[i].hi[0] : -big;
      node.hi_y[i] = used ? children[i].hi[1] : -big;
      node.hi_z[i] = used ? children[i].hi[2] : -big;
      node.child[i] = child;
      node.count[i] = used ? children[i].count : 0u;
    }
    return index;
  }

 private:
  const FlatBvh& bvh_;
  std::vector<Node>& out_;
};

}  // namespace

double collapse_bvh(FlatBvh& bvh, int width) {
  const auto start = std::chrono::steady_clock::now();
  if (bvh.nodes.empty()) throw std::invalid_argument("collapse_bvh: the BVH has no nodes");
  // The wide closest-hit traversal packs a leaf into one stack word (first | count << 29).
  if (bvh.triangles.size() >= kWideIndexLimit || bvh.nodes.size() >= kWideIndexLimit)
    throw std::runtime_error("BVH: too many triangles for the wide layout (2^29 leaf entries at most)");
  // Every wide node stands for a binary node, so the binary count bounds the wide one: reserved
  // in full, the array never grows by copying. A guess below it (a quarter of the binary nodes
  // for wide8) had the 4M smooth heightfield's 303k wide nodes outgrow 260k, and the copy into
  // twice the block held both at once: 60 MiB on top of the start's highest point. Pages
  // reserved and never written are never resident.
  if (width == 4) {
    bvh.nodes4.clear();
    bvh.nodes4.reserve(bvh.nodes.size());
    Collapser<4, Bvh4Node>(bvh, bvh.nodes4).emit(0);
  } else if (width == 8) {
    bvh.nodes8.clear();
    bvh.nodes8.reserve(bvh.nodes.size());
    Collapser<8, Bvh8Node>(bvh, bvh.nodes8).emit(0);
  } else {
    throw std::invalid_argument("collapse_bvh: width must be 4 or 8");
  }
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

BvhLeafBlock leaf_block(const std::vector<BvhTriangle>& tris, std::uint32_t first, std::uint32_t count) {
  if (count == 0 || count > 4 || first + std::uint64_t{count} > tris.size())
    throw std::runtime_error("BVH: leaf out of range in the wide layout");
  BvhLeafBlock b;
  b.first = first;
  b.count = count;
  b.flags = 0;
  b.pad = 0;
  for (std::uint32_t j = 0; j < 4; ++j) {
    const BvhTriangle& t = tris[first + (j < count ? j : 0)];
    if (j < count) b.flags |= t.flags;
    for (int k = 0; k < 3; ++k) {
      b.v[k][j] = t.v0[k];
      b.v[3 + k][j] = t.v1[k];
      b.v[6 + k][j] = t.v2[k];
    }
  }
  return b;
}

namespace {

// Where the leaves start: count_at[i] is the triangle count of the leaf whose first entry is i
// (0: none starts there), and block_at(first) the rank of that leaf among the leaves in entry
// order, which is where its block goes (leaf blocks are stored in leaf order: entry order, so a
// pass over the leaf triangles from first to last writes them front to back). One byte per
// entry and one word per 64 entries, so that nothing of the size of the triangle array stands
// beside it.
struct LeafStarts {
  std::vector<std::uint8_t> count_at;
  std::vector<std::uint32_t> rank64;  // leaves starting before entry 64 c
  std::size_t leaves = 0;

  template <int W, typename Node>
  static LeafStarts of(const std::vector<Node>& nodes, std::size_t entries) {
    LeafStarts s;
    s.scan<W>(nodes, entries);
    return s;
  }
  template <int W, typename Node>
  void scan(const std::vector<Node>& nodes, std::size_t entries) {
    count_at.assign(entries, 0);
    if (nodes.empty()) throw std::invalid_argument("device_wide_nodes: the wide nodes are not built");
    for (const Node& n : nodes)
      for (int i = 0; i < W; ++i) {
        if (n.count[i] == 0) continue;
        const std::uint32_t first = n.child[i], count = n.count[i];
        if (count > 4 || first + std::uint64_t{count} > entries || count_at[first] != 0)
          throw std::runtime_error("BVH: leaf out of range in the wide layout");
        count_at[first] = static_cast<std::uint8_t>(count);
        ++leaves;
      }
    rank64.resize(entries / 64 + 1);
    std::uint32_t r = 0;
    for (std::size_t i = 0; i < entries; ++i) {
      if (i % 64 == 0) rank64[i / 64] = r;
      r += count_at[i] != 0 ? 1 : 0;
    }
  }
  std::size_t block_at(std::uint32_t first) const {
    std::size_t r = rank64[first / 64];
    for (std::size_t i = first / 64 * 64; i < first; ++i) r += count_at[i] != 0 ? 1 : 0;
    return r;
  }
};

// The bytes of the device form: the nodes, then one leaf block per leaf slot.
template <typename Node>
std::size_t device_form_bytes(std::size_t node_count, std::size_t leaves) {
  static_assert(sizeof(Node) % 16 == 0 && sizeof(BvhLeafBlock) % 16 == 0);
  const std::size_t bytes = node_count * sizeof(Node) + leaves * sizeof(BvhLeafBlock);
  if (bytes / 16 >= kWideIndexLimit)
    throw std::runtime_error("BVH: wide node buffer too large for 29-bit leaf offsets");
  return bytes;
}

// Writes node `n` (whose leaf slots hold their first triangle) as node `k` of the device form
// at `bytes`, its leaf slots pointing at their blocks behind the `node_count` nodes, the count
// in the top 3 bits (types.h: the slot's whole stack entry in one word).
template <int W, typename Node>
void write_device_node(Node n, std::size_t k, std::size_t node_count, const LeafStarts& starts, unsigned char* bytes) {
  for (int i = 0; i < W; ++i)
    if (n.count[i] != 0)
      n.child[i] = static_cast<std::uint32_t>(
                       (node_count * sizeof(Node) + starts.block_at(n.child[i]) * sizeof(BvhLeafBlock)) / 16) |
                   (n.count[i] << 29);
  std::memcpy(bytes + k * sizeof(Node), &n, sizeof n);
}

// Hands the whole pages of [begin, end) back to the system (MADV_DONTNEED): memory of a large
// array that is dead but not yet freed. The array must be its own mapping (glibc serves blocks
// of this size with mmap), hence only from kReleaseFrom bytes on.
constexpr std::size_t kReleaseFrom = std::size_t{8} << 20;
void release_pages(const void* begin, const void* end) {
  const auto page = static_cast<std::uintptr_t>(sysconf(_SC_PAGESIZE));
  const auto b = (reinterpret_cast<std::uintptr_t>(begin) + page - 1) / page * page;
  const auto e = reinterpret_cast<std::uintptr_t>(end) / page * page;
  if (e > b) madvise(reinterpret_cast<void*>(b), e - b, MADV_DONTNEED);
}

// The leaf blocks, in leaf order, behind the nodes. With `refs`, each leaf's triangles become
// BvhLeafRef records as soon as its block is written, in the triangles' own memory (record i at
// byte 16 i, after triangle i at 48 i was read), and the pages no record will reach are handed
// back as the pass goes: at 10M triangles, the 458 MiB of leaf triangles shrink to 153 MiB while
// the blocks (395 MiB) are written, instead of standing whole beside them.
template <typename Node>
void write_blocks(const LeafStarts& starts, std::size_t node_count, const std::vector<BvhTriangle>& tris,
                  unsigned char* bytes, LeafRefs* refs) {
  const std::size_t n = tris.size();
  auto* tri_bytes = reinterpret_cast<unsigned char*>(const_cast<BvhTriangle*>(tris.data()));
  const bool release = refs && n * sizeof(BvhTriangle) >= kReleaseFrom;
  const unsigned char* released = tri_bytes + n * sizeof(BvhLeafRef);  // below: the records' place
  std::size_t r = 0;
  for (std::uint32_t first = 0; first < n;) {
    const std::uint32_t count = starts.count_at[first];
    if (count == 0) throw std::runtime_error("BVH: a leaf triangle in no leaf of the wide layout");
    const BvhLeafBlock block = leaf_block(tris, first, count);
    const std::size_t at = node_count * sizeof(Node) + r * sizeof(BvhLeafBlock);
    std::memcpy(bytes + at, &block, sizeof block);
    if (refs) {
      static_assert(sizeof(BvhLeafRef) <= sizeof(BvhTriangle) && std::is_trivially_copyable_v<BvhTriangle>);
      for (std::uint32_t i = first; i < first + count; ++i) {
        BvhTriangle t;
        std::memcpy(&t, tri_bytes + std::size_t{i} * sizeof(BvhTriangle), sizeof t);
        const BvhLeafRef ref{t.prim, t.flags, t.material, static_cast<std::uint32_t>(at / 16)};
        std::memcpy(tri_bytes + std::size_t{i} * sizeof(BvhLeafRef), &ref, sizeof ref);
      }
      const unsigned char* read = tri_bytes + std::size_t{first + count} * sizeof(BvhTriangle);
      if (release && read - released >= std::ptrdiff_t(kReleaseFrom)) {
        release_pages(released, read);
        released = read;
      }
    }
    first += count;
    ++r;
  }
  if (release) release_pages(released, tri_bytes + n * sizeof(BvhTriangle));
}

template <int W, typename Node>
std::vector<std::uint32_t> device_form(const std::vector<Node>& nodes, const std::vector<BvhTriangle>& tris) {
  // Written in place, node by node and block by block: no second copy of the nodes and no array
  // of blocks beside the buffer (at 10M triangles those had doubled the layout's 1.4 GB).
  const LeafStarts starts = LeafStarts::of<W>(nodes, tris.size());
  std::vector<std::uint32_t> words(device_form_bytes<Node>(nodes.size(), starts.leaves) / 4);
  auto* bytes = reinterpret_cast<unsigned char*>(words.data());
  write_blocks<Node>(starts, nodes.size(), tris, bytes, nullptr);
  for (std::size_t k = 0; k < nodes.size(); ++k) write_device_node<W>(nodes[k], k, nodes.size(), starts, bytes);
  return words;
}

template <int W, typename Node>
DeviceWords device_form_from(std::vector<Node>& nodes, std::vector<BvhTriangle>& tris, LeafRefs* refs) {
  const LeafStarts starts = LeafStarts::of<W>(nodes, tris.size());
  DeviceWords words;
  words.resize(device_form_bytes<Node>(nodes.size(), starts.leaves) / 4);  // uninitialised: every byte is written below
  auto* bytes = reinterpret_cast<unsigned char*>(words.data());
  const std::size_t node_count = nodes.size();
  if (refs) {
    refs->memory = std::move(tris);
    refs->count = refs->memory.size();
    write_blocks<Node>(starts, node_count, refs->memory, bytes, refs);
  } else {
    write_blocks<Node>(starts, node_count, tris, bytes, nullptr);
  }
  // The nodes, each freed (its pages handed back) once written: never held twice.
  const bool release = node_count * sizeof(Node) >= kReleaseFrom;
  const unsigned char* released = reinterpret_cast<const unsigned char*>(nodes.data());
  for (std::size_t k = 0; k < node_count; ++k) {
    write_device_node<W>(nodes[k], k, node_count, starts, bytes);
    const auto* done = reinterpret_cast<const unsigned char*>(nodes.data() + k + 1);
    if (release && done - released >= std::ptrdiff_t(kReleaseFrom)) {
      release_pages(released, done);
      released = done;
    }
  }
  std::vector<Node>().swap(nodes);
  return words;
}

}  // namespace

DeviceWords device_wide_nodes_from(FlatBvh& bvh, BvhLayout layout, LeafRefs* refs) {
  if (layout == BvhLayout::Wide4) return device_form_from<4>(bvh.nodes4, bvh.triangles, refs);
  if (layout == BvhLayout::Wide8) return device_form_from<8>(bvh.nodes8, bvh.triangles, refs);
  throw std::invalid_argument("device_wide_nodes_from: not Wide4 or Wide8");
}

std::vector<std::uint32_t> device_wide_nodes(const FlatBvh& bvh, BvhLayout layout) {
  if (layout == BvhLayout::Wide4) return device_form<4>(bvh.nodes4, bvh.triangles);
  if (layout == BvhLayout::Wide8) return device_form<8>(bvh.nodes8, bvh.triangles);
  if (layout == BvhLayout::Compressed8) return device_compressed_nodes(bvh);
  throw std::invalid_argument("device_wide_nodes: not a wide layout");
}

bool has_layout(const FlatBvh& bvh, BvhLayout layout) {
  switch (layout) {
    case BvhLayout::Binary: return true;
    case BvhLayout::Wide4: return !bvh.nodes4.empty();
    case BvhLayout::Wide8: return !bvh.nodes8.empty();
    case BvhLayout::Compressed8: return !bvh.cnodes.empty();
  }
  return false;
}

double ensure_layout(FlatBvh& bvh, BvhLayout layout) {
  if (layout == BvhLayout::Wide4 && bvh.nodes4.empty()) return collapse_bvh(bvh, 4);
  if (layout == BvhLayout::Wide8 && bvh.nodes8.empty()) return collapse_bvh(bvh, 8);
  if (layout == BvhLayout::Compressed8 && bvh.cnodes.empty()) return compress_bvh8(bvh);
  return 0.0;
}

}  // namespace px
