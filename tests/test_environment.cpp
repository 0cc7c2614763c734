// host/io/environment.h: every PARALLAX_ variable parsed into its field, `off` the one word for
// off, and a value not understood reported naming the variable (never silently ignored).
#include "io/environment.h"
#include "support/scoped_env.h"

#include <gtest/gtest.h>

#include <map>
#include <string>

namespace px {
namespace {

Environment parse(const std::map<std::string, std::string>& vars) {
  return parse_environment([&](const char* name) -> const char* {
    const auto it = vars.find(name);
    return it == vars.end() ? nullptr : it->second.c_str();
  });
}

TEST(Environment, NothingSetGivesTheDefaults) {
  const Environment e = parse({});
  EXPECT_EQ(e.platform, "");
  EXPECT_TRUE(e.pocl_launch_guard);
  EXPECT_EQ(e.max_alloc_bytes, 0u);
  EXPECT_EQ(e.image_codec, "");
  EXPECT_TRUE(e.bvh_cache);
  EXPECT_EQ(e.cache_dir, "");
  EXPECT_TRUE(e.huge_pages);
  EXPECT_TRUE(e.problems.empty());
}

TEST(Environment, EveryVariableReachesItsField) {
  const Environment e = parse({{"PARALLAX_PLATFORM", "Portable"},
                               {"PARALLAX_POCL_LAUNCH_GUARD", "off"},
                               {"PARALLAX_MAX_ALLOC_BYTES", "1000"},
                               {"PARALLAX_IMAGE_CODEC", "/x/codec.so"},
                               {"PARALLAX_BVH_CACHE", "off"},
                               {"PARALLAX_CACHE_DIR", "/tmp/c"},
                               {"PARALLAX_HUGE_PAGES", "off"}});
  EXPECT_EQ(e.platform, "Portable");
  EXPECT_FALSE(e.pocl_launch_guard);
  EXPECT_EQ(e.max_alloc_bytes, 1000u);
  EXPECT_EQ(e.image_codec, "/x/codec.so");
  EXPECT_FALSE(e.bvh_cache);
  EXPECT_EQ(e.cache_dir, "/tmp/c");
  EXPECT_FALSE(e.huge_pages);
  EXPECT_TRUE(e.problems.empty());
  EXPECT_TRUE(parse({{"PARALLAX_HUGE_PAGES", "on"}}).huge_pages);
}

TEST(Environment, AValueNotUnderstoodIsReportedNamingTheVariable) {
  for (const char* name : {"PARALLAX_POCL_LAUNCH_GUARD", "PARALLAX_BVH_CACHE", "PARALLAX_HUGE_PAGES"})
    for (const char* value : {"0", "no", "OFF"}) {
      const Environment e = parse({{name, value}});
      ASSERT_EQ(e.problems.size(), 1u) << name << "=" << value;
      EXPECT_NE(e.problems[0].find(std::string(name) + "=" + value), std::string::npos) << e.problems[0];
      EXPECT_TRUE(e.pocl_launch_guard && e.bvh_cache && e.huge_pages) << "the default stays";
    }
  for (const char* value : {"abc", "-5", "0", "12kb"}) {
    const Environment e = parse({{"PARALLAX_MAX_ALLOC_BYTES", value}});
    ASSERT_EQ(e.problems.size(), 1u) << value;
    EXPECT_NE(e.problems[0].find("PARALLAX_MAX_ALLOC_BYTES"), std::string::npos) << e.problems[0];
    EXPECT_EQ(e.max_alloc_bytes, 0u);
  }
}

TEST(Environment, AScopedVariableIsSeenForItsScopeOnly) {
  const std::string before = environment().cache_dir;
  {
    const test::ScopedEnv dir("PARALLAX_CACHE_DIR", "/tmp/scoped-env-test");
    EXPECT_EQ(environment().cache_dir, "/tmp/scoped-env-test");
  }
  EXPECT_EQ(environment().cache_dir, before);
}

}  // namespace
}  // namespace px
