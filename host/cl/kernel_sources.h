// The kernels/ tree, embedded at build time (cmake/embed_kernels.cmake), and the resolver
// that turns one kernel file and its #includes into a single OpenCL C source.
#pragma once

#include <map>
#include <string>
#include <vector>

namespace px {

// Relative path under kernels/ -> file text.
const std::map<std::string, std::string>& kernel_sources();

// Inlines every `#include "path"` (paths relative to kernels/, each file once) and emits
// #line markers so compiler diagnostics name the original file and line.
// Throws ClFailure when a file or include is not found.
std::string resolve_kernel_source(const std::string& path);

// The files `path` itself includes with `#include "path"`, in order (not their includes).
// Throws ClFailure when the file is not found or an include is malformed.
std::vector<std::string> quoted_includes(const std::string& path);

}  // namespace px
