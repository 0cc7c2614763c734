#include "cl/kernel_sources.h"

#include "cl/cl_error.h"

#include <set>
#include <sstream>

namespace px {
namespace {

void append_resolved(const std::string& path, std::set<std::string>& seen, std::string& out) {
  if (!seen.insert(path).second) return;  // every header is include-guarded: once is enough
  const auto& table = kernel_sources();
  auto it = table.find(path);
  if (it == table.end()) throw ClFailure("kernel source not found: kernels/" + path);

  std::istringstream in(it->second);
  std::string line;
  int number = 0;
  out += "#line 1 \"" + path + "\"\n";
  while (std::getline(in, line)) {
    ++number;
    auto first = line.find_first_not_of(" \t");
    // Quoted includes are inlined; <...> includes are left for the compiler (the shared header
    // has host-only ones inside #ifndef __OPENCL_C_VERSION__).
    if (first != std::string::npos && line.compare(first, 8, "#include") == 0 &&
        line.find('<', first) == std::string::npos) {
      auto open = line.find('"', first);
      auto close = open == std::string::npos ? open : line.find('"', open + 1);
      if (close == std::string::npos)
        throw ClFailure("kernels/" + path + ":" + std::to_string(number) + ": malformed #include");
      append_resolved(line.substr(open + 1, close - open - 1), seen, out);
      out += "#line " + std::to_string(number + 1) + " \"" + path + "\"\n";
      continue;
    }
    out += line;
    out += '\n';
  }
}

}  // namespace

std::string resolve_kernel_source(const std::string& path) {
  std::set<std::string> seen;
  std::string out;
  append_resolved(path, seen, out);
  return out;
}

}  // namespace px
