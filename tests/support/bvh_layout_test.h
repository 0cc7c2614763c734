// Tests that run once per BVH node layout (binary, 4-wide, 8-wide, compressed 8-wide): the
// layout belongs to a device set (DeviceOptions::bvh_layout), so the fixture gives each test
// the options and a kept one-device set in its layout.
#pragma once

#include "bvh/bvh_layout.h"
#include "cl/device_set.h"

#include <gtest/gtest.h>

#include <map>
#include <memory>
#include <string>

namespace px::test {

// Device options asking for `layout`.
inline DeviceOptions options_in_layout(BvhLayout layout, int count = 1, DeviceMode mode = DeviceMode::Auto) {
  DeviceOptions options{count, mode, "", std::nullopt};
  options.bvh_layout = layout;
  return options;
}

// One device in `layout`, made at the first call and kept for the process.
inline DeviceSet& device_in_layout(BvhLayout layout) {
  static std::map<BvhLayout, std::unique_ptr<DeviceSet>> sets;
  auto& set = sets[layout];
  if (!set) set = std::make_unique<DeviceSet>(DeviceSet::create(options_in_layout(layout)));
  return *set;
}

class BvhLayoutTest : public ::testing::TestWithParam<BvhLayout> {
 protected:
  BvhLayout layout() const { return GetParam(); }
  DeviceSet& layout_device() const { return device_in_layout(GetParam()); }
  DeviceOptions layout_options(int count = 1, DeviceMode mode = DeviceMode::Auto) const {
    return options_in_layout(GetParam(), count, mode);
  }
};

// Every layout, for INSTANTIATE_TEST_SUITE_P, and the test name suffix of each.
inline auto all_bvh_layouts() {
  return ::testing::Values(BvhLayout::Binary, BvhLayout::Wide4, BvhLayout::Wide8, BvhLayout::Compressed8);
}
inline std::string bvh_layout_name(const ::testing::TestParamInfo<BvhLayout>& info) { return to_string(info.param); }

}  // namespace px::test
