#include "support/test_support.h"

namespace px::test {

std::filesystem::path shared_dir() {
  std::filesystem::path p = PX_SHARED_DIR;
  std::error_code ec;
  if (std::filesystem::is_directory(p, ec)) return std::filesystem::canonical(p, ec);
  return {};
}

std::filesystem::path source_dir() { return PX_SOURCE_DIR; }

}  // namespace px::test
