#include "cl/kernel_sources.h"

#include "cl/cl_error.h"

#include <set>
#include <sstream>
#include <utility>

namespace px {
namespace {

const std::string& source_of(const std::string& path) {
  const auto& table = kernel_sources();
  auto it = table.find(path);
  if (it == table.end()) throw ClFailure("kernel source not found: kernels/" + path);
  return it->second;
}

// The file a line `#include "file"` names, or "" for any other line. Quoted includes are ours;
// <...> includes are left for the compiler (the shared header has host-only ones inside
// #ifndef __OPENCL_C_VERSION__).
std::string quoted_include(const std::string& line, const std::string& path, int number) {
  const auto first = line.find_first_not_of(" \t");
  if (first == std::string::npos || line.compare(first, 8, "#include") != 0 ||
      line.find('<', first) != std::string::npos)
    return {};
  const auto open = line.find('"', first);
  const auto close = open == std::string::npos ? open : line.find('"', open + 1);
  if (close == std::string::npos)
    throw ClFailure("kernels/" + path + ":" + std::to_string(number) + ": malformed #include");
  return line.substr(open + 1, close - open - 1);
}

void append_resolved(const std::string& path, std::set<std::string>& seen, std::string& out) {
  if (!seen.insert(path).second) return;  // every header is include-guarded: once is enough
  std::istringstream in(source_of(path));
  std::string line;
  int number = 0;
  out += "#line 1 \"" + path + "\"\n";
  while (std::getline(in, line)) {
    ++number;
    if (const std::string included = quoted_include(line, path, number); !included.empty()) {
      append_resolved(included, seen, out);
      out += "#line " + std::to_string(number + 1) + " \"" + path + "\"\n";
      continue;
    }
    out += line;
    out += '\n';
  }
}

}  // namespace

std::vector<std::string> quoted_includes(const std::string& path) {
  std::istringstream in(source_of(path));
  std::vector<std::string> files;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number)
    if (std::string included = quoted_include(line, path, number); !included.empty())
      files.push_back(std::move(included));
  return files;
}

std::string resolve_kernel_source(const std::string& path) {
  std::set<std::string> seen;
  std::string out;
  append_resolved(path, seen, out);
  return out;
}

}  // namespace px
