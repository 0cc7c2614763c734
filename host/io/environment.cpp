#include "io/environment.h"

#include <cerrno>
#include <cstdio>
#include <cstdlib>

namespace px {
namespace {

// A switch: unset, empty or `on` = on; `off` = off; anything else is reported and leaves it on.
bool parse_switch(const char* name, const char* value, std::vector<std::string>& problems) {
  if (!value || !*value) return true;
  const std::string v = value;
  if (v == "off") return false;
  if (v != "on")
    problems.push_back(std::string(name) + "=" + v + " is not understood (only 'off' or 'on'); it stays on");
  return true;
}

std::size_t parse_bytes(const char* name, const char* value, std::vector<std::string>& problems) {
  if (!value || !*value) return 0;
  char* end = nullptr;
  errno = 0;
  const unsigned long long v = std::strtoull(value, &end, 10);
  if (errno != 0 || *end != '\0' || v == 0 || value[0] == '-') {
    problems.push_back(std::string(name) + "=" + value +
                       " is not understood (a positive number of bytes); the devices' own limit stays");
    return 0;
  }
  return static_cast<std::size_t>(v);
}

std::string text(const char* value) { return value ? value : ""; }

// Never destroyed: read from operator new (huge_page_allocation.cpp), which may run during static
// destruction.
Environment*& current() {
  static Environment* env = nullptr;
  return env;
}

Environment* read_and_report() {
  auto* env = new Environment(parse_environment([](const char* name) { return std::getenv(name); }));
  for (const std::string& p : env->problems) std::fprintf(stderr, "parallax: warning: %s\n", p.c_str());
  return env;
}

}  // namespace

Environment parse_environment(const std::function<const char*(const char*)>& lookup) {
  Environment e;
  e.platform = text(lookup("PARALLAX_PLATFORM"));
  e.pocl_launch_guard = parse_switch("PARALLAX_POCL_LAUNCH_GUARD", lookup("PARALLAX_POCL_LAUNCH_GUARD"), e.problems);
  e.max_alloc_bytes = parse_bytes("PARALLAX_MAX_ALLOC_BYTES", lookup("PARALLAX_MAX_ALLOC_BYTES"), e.problems);
  e.image_codec = text(lookup("PARALLAX_IMAGE_CODEC"));
  e.bvh_cache = parse_switch("PARALLAX_BVH_CACHE", lookup("PARALLAX_BVH_CACHE"), e.problems);
  e.cache_dir = text(lookup("PARALLAX_CACHE_DIR"));
  e.huge_pages = parse_switch("PARALLAX_HUGE_PAGES", lookup("PARALLAX_HUGE_PAGES"), e.problems);
  e.indexed_shading = parse_switch("PARALLAX_INDEXED_SHADING", lookup("PARALLAX_INDEXED_SHADING"), e.problems);
  return e;
}

const Environment& environment() {
  static Environment* const first = current() = read_and_report();
  (void)first;
  return *current();
}

void reload_environment_for_tests() {
  environment();                  // the first read, if it has not happened
  current() = read_and_report();  // the previous one is leaked: a reader may still hold it
}

}  // namespace px
