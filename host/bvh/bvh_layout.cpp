// BvhLayout's names and each device type's default layout.
#include "bvh/bvh_layout.h"

#include <stdexcept>
#include <string>

namespace px {

namespace {

// The defaults per device type when no layout is requested (bvh_layout.h: bvh_layout_for says why).
constexpr BvhLayout kCpuBvhLayout = BvhLayout::Wide8;
constexpr BvhLayout kGpuBvhLayout = BvhLayout::Binary;

}  // namespace

BvhLayout bvh_layout_for(bool all_gpus) { return all_gpus ? kGpuBvhLayout : kCpuBvhLayout; }

const char* to_string(BvhLayout layout) {
  switch (layout) {
    case BvhLayout::Binary: return "binary";
    case BvhLayout::Wide4: return "wide4";
    case BvhLayout::Wide8: return "wide8";
    case BvhLayout::Compressed8: return "cwbvh";
  }
  return "?";
}

BvhLayout parse_bvh_layout(const std::string& name) {
  if (name == "binary" || name == "2") return BvhLayout::Binary;
  if (name == "wide4" || name == "4") return BvhLayout::Wide4;
  if (name == "wide8" || name == "8") return BvhLayout::Wide8;
  if (name == "cwbvh" || name == "compressed8") return BvhLayout::Compressed8;
  throw std::invalid_argument("unknown BVH layout '" + name + "' (binary, wide4, wide8 or cwbvh)");
}

}  // namespace px
