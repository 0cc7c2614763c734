// compress_bvh8(): the 8-wide tree (Bvh8Node) re-stored with quantized child boxes
// (CompressedBvh8Node, types.h), after the idea of Ylitie, Karras & Laine 2017: a per-node grid
// of 2^e steps from an origin p, child boxes as 8-bit grid coordinates rounded outward.
//
// The grid is chosen so that decoding is exact: p and every p + q * 2^e (q = 0..255) is an
// integer multiple of 2^e of magnitude <= 2^24 * 2^e, which a float represents exactly. The
// kernels' q * scale + p then rounds nowhere (fused or not), the decoded planes are exactly the
// ones checked here, and outward rounding of q is exact arithmetic rather than a float
// computation that could round the wrong way.
#include "bvh/compressed_bvh.h"

#include "bvh/wide_bvh.h"

#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

namespace px {

namespace {

constexpr int kExponentBias = 127;
constexpr int kMinExponent = 1 - kExponentBias;    // smallest normal float scale, 2^-126
constexpr int kMaxExponent = 246 - kExponentBias;  // 255 * 2^119 is still a finite float
constexpr double kExactLimit = 16777216.0;         // 2^24: integers up to it are exact floats

// One axis of a node's grid: origin p = k * 2^exponent.
struct AxisGrid {
  int exponent;
  double scale;
  double k;  // p / scale, an integer
};

// The smallest grid that covers [lo, hi] in 255 steps from a p on the grid, with all 256
// planes exact floats.
AxisGrid choose_grid(float lo, float hi) {
  const double extent = double(hi) - double(lo);
  // A starting exponent no larger than the answer (the loop only goes up): 2^e >= extent / 255
  // needs e >= log2(extent / 255); one below that, for rounding in log2.
  int e = kMinExponent;
  if (extent > 0.0) e = std::max(e, static_cast<int>(std::floor(std::log2(extent / 255.0))) - 1);
  for (; e <= kMaxExponent; ++e) {
    const double scale = std::ldexp(1.0, e);
    const double k = std::floor(double(lo) / scale);            // lo / scale is exact (power of two)
    if (k < -kExactLimit || k + 255.0 > kExactLimit) continue;  // planes not all exact floats
    if ((k + 255.0) * scale < double(hi)) continue;             // 255 steps do not reach hi
    return {e, scale, k};
  }
  throw std::runtime_error("BVH: a node's extent is too large for the compressed layout");
}

// Grid coordinate of a child's min plane: the largest q with p + q * scale <= lo. The
// comparisons are exact: (k + q) * scale is an exact float (choose_grid), so also exact in double.
std::uint8_t quantize_down(const AxisGrid& g, float lo) {
  double q = std::floor(double(lo) / g.scale - g.k);
  q = std::min(255.0, std::max(0.0, q));
  while (q > 0.0 && (g.k + q) * g.scale > double(lo)) q -= 1.0;
  while (q < 255.0 && (g.k + q + 1.0) * g.scale <= double(lo)) q += 1.0;
  if ((g.k + q) * g.scale > double(lo)) throw std::logic_error("compress_bvh8: child box below its node's grid");
  return static_cast<std::uint8_t>(q);
}

// The smallest q with p + q * scale >= hi.
std::uint8_t quantize_up(const AxisGrid& g, float hi) {
  double q = std::ceil(double(hi) / g.scale - g.k);
  q = std::min(255.0, std::max(0.0, q));
  while (q < 255.0 && (g.k + q) * g.scale < double(hi)) q += 1.0;
  while (q > 0.0 && (g.k + q - 1.0) * g.scale >= double(hi)) q -= 1.0;
  if ((g.k + q) * g.scale < double(hi)) throw std::logic_error("compress_bvh8: child box above its node's grid");
  return static_cast<std::uint8_t>(q);
}

class Compressor {
 public:
  explicit Compressor(FlatBvh& bvh) : bvh_(bvh) {}

  // Writes compressed node `out` for Bvh8Node `in`, allocating its interior children as one
  // block at the end of cnodes and its leaves as one run at the end of cleaf_first, then fills
  // the children (recursion depth = tree depth <= PX_BVH_MAX_DEPTH).
  void fill(std::uint32_t in, std::uint32_t out) {
    const Bvh8Node& n = bvh_.nodes8[in];
    CompressedBvh8Node c;
    std::memset(&c, 0, sizeof c);
    std::memset(c.qlo_x, 255, sizeof c.qlo_x);  // unused slots: inverted boxes (types.h)
    std::memset(c.qlo_y, 255, sizeof c.qlo_y);
    std::memset(c.qlo_z, 255, sizeof c.qlo_z);

    // The node's box: the union of its children's.
    float lo[3] = {std::numeric_limits<float>::max(), std::numeric_limits<float>::max(),
                   std::numeric_limits<float>::max()};
    float hi[3] = {-lo[0], -lo[1], -lo[2]};
    for (int i = 0; i < 8; ++i) {
      if (is_absent_slot(n, i)) continue;
      const float clo[3] = {n.lo_x[i], n.lo_y[i], n.lo_z[i]}, chi[3] = {n.hi_x[i], n.hi_y[i], n.hi_z[i]};
      for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], clo[k]), hi[k] = std::max(hi[k], chi[k]);
    }
    if (lo[0] > hi[0]) throw std::runtime_error("compress_bvh8: a wide node has no children");
    AxisGrid grid[3];
    for (int k = 0; k < 3; ++k) {
      grid[k] = choose_grid(lo[k], hi[k]);
      c.p[k] = static_cast<float>(grid[k].k * grid[k].scale);  // exact
      c.e[k] = static_cast<std::uint8_t>(grid[k].exponent + kExponentBias);
    }

    std::uint32_t interior_in[8];
    int interior = 0, leaves = 0;
    c.child_base = static_cast<std::uint32_t>(bvh_.cnodes.size());
    c.leaf_base = static_cast<std::uint32_t>(bvh_.cleaf_first.size());
    for (int i = 0; i < 8; ++i) {
      if (is_absent_slot(n, i)) continue;
      const float clo[3] = {n.lo_x[i], n.lo_y[i], n.lo_z[i]}, chi[3] = {n.hi_x[i], n.hi_y[i], n.hi_z[i]};
      std::uint8_t* qlo[3] = {c.qlo_x, c.qlo_y, c.qlo_z};
      std::uint8_t* qhi[3] = {c.qhi_x, c.qhi_y, c.qhi_z};
      for (int k = 0; k < 3; ++k) {
        qlo[k][i] = quantize_down(grid[k], clo[k]);
        qhi[k][i] = quantize_up(grid[k], chi[k]);
      }
      if (n.count[i] == 0) {
        c.imask |= static_cast<std::uint8_t>(1u << i);
        c.meta[i] = static_cast<std::uint8_t>(PX_CWBVH_META_USED | interior);
        interior_in[interior++] = n.child[i];
      } else {
        if (n.count[i] > PX_BVH_MAX_LEAF_SIZE) throw std::runtime_error("compress_bvh8: leaf too large");
        c.meta[i] = static_cast<std::uint8_t>(PX_CWBVH_META_USED | (n.count[i] << PX_CWBVH_META_COUNT_SHIFT) |
                                              static_cast<unsigned>(leaves++));
        bvh_.cleaf_first.push_back(n.child[i]);
      }
    }
    bvh_.cnodes.resize(bvh_.cnodes.size() + interior);
    bvh_.cnodes[out] = c;
    for (int r = 0; r < interior; ++r) fill(interior_in[r], c.child_base + r);
  }

 private:
  FlatBvh& bvh_;
};

}  // namespace

double compress_bvh8(FlatBvh& bvh) {
  const auto start = std::chrono::steady_clock::now();
  if (bvh.nodes8.empty()) collapse_bvh(bvh, 8);
  bvh.cnodes.clear();
  bvh.cleaf_first.clear();
  bvh.cnodes.reserve(bvh.nodes8.size());
  bvh.cnodes.resize(1);
  Compressor(bvh).fill(0, 0);
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

std::vector<std::uint32_t> device_compressed_nodes(const FlatBvh& bvh) {
  static_assert(sizeof(CompressedBvh8Node) % 16 == 0 && sizeof(BvhLeafBlock) == PX_LEAF_BLOCK_UNITS * 16);
  if (bvh.cnodes.empty()) throw std::invalid_argument("device_compressed_nodes: the compressed nodes are not built");
  const std::size_t leaves = bvh.cleaf_first.size();
  const std::size_t node_bytes = bvh.cnodes.size() * sizeof(CompressedBvh8Node);
  if ((node_bytes + leaves * sizeof(BvhLeafBlock)) / 16 >= kWideIndexLimit)
    throw std::runtime_error("BVH: compressed node buffer too large for 29-bit leaf offsets");
  // Each leaf's count is in its slot's meta byte: gather them in cleaf_first order.
  std::vector<std::uint32_t> leaf_count(leaves, 0);
  std::vector<CompressedBvh8Node> out_nodes = bvh.cnodes;
  for (CompressedBvh8Node& n : out_nodes) {
    for (int i = 0; i < 8; ++i) {
      const unsigned m = n.meta[i];
      const unsigned count = (m >> PX_CWBVH_META_COUNT_SHIFT) & 7u;
      if (m == 0 || count == 0) continue;
      const std::size_t leaf = std::size_t{n.leaf_base} + (m & PX_CWBVH_RANK_MASK);
      if (leaf >= leaves) throw std::runtime_error("BVH: leaf out of range in the compressed layout");
      leaf_count[leaf] = count;
    }
    // Leaf blocks follow the nodes in cleaf_first order, so a node's blocks are contiguous.
    n.leaf_base = static_cast<std::uint32_t>(node_bytes / 16 + std::size_t{n.leaf_base} * PX_LEAF_BLOCK_UNITS);
  }
  std::vector<std::uint32_t> words((node_bytes + leaves * sizeof(BvhLeafBlock)) / 4);
  std::memcpy(words.data(), out_nodes.data(), node_bytes);
  for (std::size_t l = 0; l < leaves; ++l) {
    const BvhLeafBlock b = leaf_block(bvh.triangles, bvh.cleaf_first[l], leaf_count[l]);
    std::memcpy(words.data() + (node_bytes + l * sizeof(BvhLeafBlock)) / 4, &b, sizeof b);
  }
  return words;
}

}  // namespace px
