#include "image/row_range.h"

#include <algorithm>
#include <stdexcept>

namespace px {

std::vector<RowRange> split_rows(unsigned height, unsigned strips) {
  if (strips == 0) throw std::invalid_argument("split_rows: zero strips");
  std::vector<RowRange> out(strips);
  const unsigned base = height / strips, extra = height % strips;
  unsigned row = 0;
  for (unsigned i = 0; i < strips; ++i) {
    out[i].begin = row;
    row += base + (i < extra ? 1 : 0);
    out[i].end = row;
  }
  return out;
}

RowRange widen(RowRange rows, unsigned radius, unsigned height) {
  if (rows.size() == 0) return {};
  return {rows.begin > radius ? rows.begin - radius : 0u, std::min(height, rows.end + radius)};
}

std::vector<RowRange> widen(const std::vector<RowRange>& rows, unsigned radius, unsigned height) {
  std::vector<RowRange> out(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) out[i] = widen(rows[i], radius, height);
  return out;
}

}  // namespace px
