// A band of full-width image rows, the unit in which work is split between devices.
#pragma once

#include <vector>

namespace px {

struct RowRange {
  unsigned begin = 0, end = 0;
  unsigned size() const { return end - begin; }
  bool operator==(const RowRange&) const = default;
};

// N contiguous full-width strips (sizes differ by at most one row, remainders to the top).
// Throws std::invalid_argument for zero strips.
std::vector<RowRange> split_rows(unsigned height, unsigned strips);

// `rows` widened by `radius` rows each side, clipped to [0, height); empty stays empty.
RowRange widen(RowRange rows, unsigned radius, unsigned height);
// Each of `rows` widened so (per device: a strip and the margin a pass reads).
std::vector<RowRange> widen(const std::vector<RowRange>& rows, unsigned radius, unsigned height);

}  // namespace px
