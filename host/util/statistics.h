// Summary statistics over timings (frames of a run, repeats of a bench): the one median that
// the render summary, the animation line and the benches report.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace px {

// The median of `v`; 0 for no values. An even count gives the mean of the two middle values
// (of 2 frames, their mean; not whichever sorts last), as every summary states its medians.
inline double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2) return *mid;
  // The lower middle value is the largest of those nth_element put before `mid`.
  return 0.5 * (*std::max_element(v.begin(), mid) + *mid);
}

}  // namespace px
