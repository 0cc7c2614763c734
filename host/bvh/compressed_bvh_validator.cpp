// validate_compressed(): the compressed nodes' encoding, and each decoded box against the exact
// Bvh8Node box it stands for.
#include "bvh/compressed_bvh_validator.h"

#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

namespace px::bvh_validation {

void validate_compressed(const FlatBvh& bvh, Report& report) {
  const auto& cn = bvh.cnodes;
  if (bvh.nodes8.empty()) {
    report.error("cwbvh nodes are present without the wide8 nodes they are built from");
    return;
  }
  std::vector<std::uint8_t> seen(cn.size(), 0);
  std::vector<std::pair<std::uint32_t, std::uint32_t>> stack{{0u, 0u}};  // (cnode, node8)
  while (!stack.empty()) {
    const auto [c, w] = stack.back();
    stack.pop_back();
    if (c >= cn.size() || w >= bvh.nodes8.size() || seen[c]) continue;  // reported by the walk
    seen[c] = 1;
    const CompressedBvh8Node& n = cn[c];
    const Bvh8Node& ref = bvh.nodes8[w];
    bool encoding_ok = true;
    for (int k = 0; k < 3; ++k)
      if (n.e[k] < 1 || n.e[k] > 246) {
        report.error("cwbvh node ", c, " has scale exponent ", int(n.e[k]), " on axis ", k, " (1..246)");
        encoding_ok = false;
      }
    if (!encoding_ok) continue;
    const std::uint8_t* qlo[3] = {n.qlo_x, n.qlo_y, n.qlo_z};
    const std::uint8_t* qhi[3] = {n.qhi_x, n.qhi_y, n.qhi_z};
    const float* rlo[3] = {ref.lo_x, ref.lo_y, ref.lo_z};
    const float* rhi[3] = {ref.hi_x, ref.hi_y, ref.hi_z};
    unsigned interior = 0, leaves = 0;
    for (int i = 0; i < 8; ++i) {
      const std::uint8_t m = n.meta[i];
      const bool ref_used = !is_absent_slot(ref, i);
      const bool is_interior = m != 0 && meta_count(m) == 0;
      if (((n.imask >> i) & 1u) != (is_interior ? 1u : 0u))
        report.error("cwbvh node ", c, " slot ", i, ": imask and meta disagree");
      if (m == 0) {
        for (int k = 0; k < 3; ++k)
          if (qlo[k][i] != 255 || qhi[k][i] != 0)
            report.error("cwbvh node ", c, " slot ", i, " is unused but its box is not inverted (255, 0)");
        if (ref_used) report.error("cwbvh node ", c, " slot ", i, " is unused but wide8 node ", w, " uses it");
        continue;
      }
      if ((m & PX_CWBVH_META_USED) == 0 || (m & 0x40u) != 0 || meta_count(m) > PX_BVH_MAX_LEAF_SIZE) {
        report.error("cwbvh node ", c, " slot ", i, " has an invalid meta byte ", unsigned(m));
        continue;
      }
      const unsigned expected_rank = is_interior ? interior++ : leaves++;
      if (meta_rank(m) != expected_rank)
        report.error("cwbvh node ", c, " slot ", i, " has rank ", meta_rank(m), ", expected ", expected_rank);
      if (!ref_used) {
        report.error("cwbvh node ", c, " slot ", i, " is used but wide8 node ", w, " leaves it unused");
        continue;
      }
      if (meta_count(m) != ref.count[i])
        report.error("cwbvh node ", c, " slot ", i, " holds ", meta_count(m), " triangles, wide8 ", ref.count[i]);
      for (int k = 0; k < 3; ++k) {
        if (qlo[k][i] > qhi[k][i]) report.error("cwbvh node ", c, " slot ", i, " box is inverted on axis ", k);
        for (std::uint8_t q : {qlo[k][i], qhi[k][i]}) {
          // The decoded plane must be exact (types.h), or a fused and an unfused decode differ.
          const double exact = double(n.p[k]) + double(q) * std::ldexp(1.0, int(n.e[k]) - 127);
          if (double(decode_plane(n, k, q)) != exact) {
            report.error("cwbvh node ", c, " slot ", i, ": plane ", unsigned(q), " on axis ", k,
                         " does not decode to an exact float");
            break;
          }
        }
        if (decode_plane(n, k, qlo[k][i]) > rlo[k][i] || decode_plane(n, k, qhi[k][i]) < rhi[k][i])
          report.error("cwbvh node ", c, " slot ", i, " decoded box does not contain the exact child box on axis ", k);
      }
      if (is_interior) {
        const std::uint64_t child = std::uint64_t{n.child_base} + meta_rank(m);
        if (child < cn.size()) stack.push_back({static_cast<std::uint32_t>(child), ref.child[i]});
      } else {
        const std::uint64_t leaf = std::uint64_t{n.leaf_base} + meta_rank(m);
        if (leaf >= bvh.cleaf_first.size())
          report.error("cwbvh node ", c, " slot ", i, " leaf ", leaf, " is past the ", bvh.cleaf_first.size(),
                       " leaves");
        else if (bvh.cleaf_first[leaf] != ref.child[i])
          report.error("cwbvh node ", c, " slot ", i, " leaf starts at triangle ", bvh.cleaf_first[leaf], ", wide8 at ",
                       ref.child[i]);
      }
    }
    if (std::uint64_t{n.child_base} + interior > cn.size())
      report.error("cwbvh node ", c, " interior children ", n.child_base, "..",
                   std::uint64_t{n.child_base} + interior - 1, " are past the ", cn.size(), " nodes");
  }
}

}  // namespace px::bvh_validation
