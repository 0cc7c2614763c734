#include "app/output_dir.h"

#include <cstdio>
#include <filesystem>
#include <stdexcept>

namespace px {

void prepare_output_dir(const std::string& dir, bool overwrite) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw std::runtime_error("output path " + dir + " exists and is not a directory");
  if (fs::is_directory(dir, ec)) {
    std::size_t files = 0;
    for (auto it = fs::directory_iterator(dir, ec); !ec && it != fs::directory_iterator(); ++it) ++files;
    if (files > 0) {
      if (!overwrite)
        throw std::runtime_error("output directory " + dir + " is not empty (" + std::to_string(files) +
                                 " entries); pass --overwrite to replace its files, or choose another --out");
      std::fprintf(stderr, "[out] %s is not empty: files of the same name will be overwritten\n", dir.c_str());
    }
    return;
  }
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error("cannot create output directory " + dir + ": " + ec.message());
}

}  // namespace px
