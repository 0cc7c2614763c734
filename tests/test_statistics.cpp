// util/statistics.h against a brute-force median: sort, take the middle value, or the mean of
// the two middle values for an even count.
#include "util/statistics.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

namespace px {
namespace {

double sorted_median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : (v[n / 2 - 1] + v[n / 2]) / 2.0;
}

TEST(Median, NoValuesGiveZero) { EXPECT_EQ(median({}), 0.0); }

TEST(Median, EvenCountTakesTheMeanOfTheTwoMiddleValues) {
  EXPECT_EQ(median({7.0}), 7.0);
  EXPECT_EQ(median({4.0, 1.0}), 2.5);
  EXPECT_EQ(median({10.0, 1.0, 3.0, 2.0}), 2.5);
  EXPECT_EQ(median({5.0, 1.0, 3.0}), 3.0);
  EXPECT_EQ(median({2.0, 2.0, 2.0, 9.0}), 2.0);
}

TEST(Median, EqualsASortedCopysMiddleForRandomInputs) {
  std::mt19937 rng(47);
  std::uniform_real_distribution<double> value(-100.0, 100.0);
  std::uniform_int_distribution<int> small(0, 4);  // repeated values too
  for (int trial = 0; trial < 2000; ++trial) {
    const std::size_t n = 1 + static_cast<std::size_t>(trial % 33);
    std::vector<double> v(n);
    for (double& x : v) x = trial % 2 ? value(rng) : double(small(rng));
    EXPECT_EQ(median(v), sorted_median(v)) << "n " << n << ", trial " << trial;
  }
}

}  // namespace
}  // namespace px
