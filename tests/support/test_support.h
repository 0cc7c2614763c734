// Helpers shared by the test executables.
#pragma once

#include <filesystem>
#include <string>

namespace px::test {

// ../shared beside the checkout, or "" when absent (a user's machine): tests that need it skip.
std::filesystem::path shared_dir();

// The project's source tree (for scenes/*.json).
std::filesystem::path source_dir();

// A fresh folder under the system's temporary directory, removed with everything in it when
// the object dies.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  // Writes `text` to `name` (a relative path; folders are made) and returns the full path.
  std::filesystem::path write(const std::string& name, const std::string& text) const;

 private:
  std::filesystem::path path_;
};

}  // namespace px::test
