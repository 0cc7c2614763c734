/* Prefix sums over a work-group, for stream compaction: each work-item learns where its
 * entries go among the group's, and one work-item reserves the group's whole range in the
 * global list with a single atomic_add. Neighbouring work-items' entries stay neighbours, in
 * order (unlike an atomic_inc per item, which scatters them and, on a GPU, serializes on one
 * counter); ranges of different groups land in whatever order the groups finish. */
#ifndef PARALLAX_GROUP_SCAN_H
#define PARALLAX_GROUP_SCAN_H

#include "shared/types.h"

/* Inclusive prefix sum of `v` over the work-group: the sum of v over work-items 0..lid.
 * Hillis-Steele in local memory, log2(PX_LOCAL_SIZE) steps; `scan` is PX_LOCAL_SIZE uints of
 * local memory, and scan[PX_LOCAL_SIZE - 1] holds the group's total afterwards. It holds
 * barriers: every work-item of the group must call it (no early return before it), and the
 * kernel must run with PX_LOCAL_SIZE work-items per group. */
inline uint px_group_inclusive_scan(uint v, local uint* scan) {
  const uint lid = get_local_id(0);
  scan[lid] = v;
  barrier(CLK_LOCAL_MEM_FENCE);
  for (uint offset = 1; offset < PX_LOCAL_SIZE; offset <<= 1) {
    const uint add = lid >= offset ? scan[lid - offset] : 0u;
    barrier(CLK_LOCAL_MEM_FENCE);
    scan[lid] += add;
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  return scan[lid];
}

#endif
