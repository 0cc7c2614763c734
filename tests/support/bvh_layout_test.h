// Tests that run once per BVH node layout (binary, 4-wide, 8-wide, compressed 8-wide): the
// layout is process-wide, so the fixture sets it before the test builds its trees and device
// scenes, and puts the previous one back after.
#pragma once

#include "bvh/flat_bvh.h"

#include <gtest/gtest.h>

#include <optional>
#include <string>

namespace px::test {

class BvhLayoutTest : public ::testing::TestWithParam<BvhLayout> {
 protected:
  void SetUp() override {
    saved_ = requested_bvh_layout();
    set_bvh_layout(GetParam());
  }
  void TearDown() override { set_bvh_layout(saved_); }

 private:
  std::optional<BvhLayout> saved_;
};

// Every layout, for INSTANTIATE_TEST_SUITE_P, and the test name suffix of each.
inline auto all_bvh_layouts() {
  return ::testing::Values(BvhLayout::Binary, BvhLayout::Wide4, BvhLayout::Wide8, BvhLayout::Compressed8);
}
inline std::string bvh_layout_name(const ::testing::TestParamInfo<BvhLayout>& info) {
  return to_string(info.param);
}

}  // namespace px::test
