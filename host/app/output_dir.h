// Output directories are never silently mixed or lost.
//  - A run claims its --out folder for its whole duration with a lock file created atomically
//    (O_CREAT | O_EXCL) *before* the emptiness check, so of two runs started on one fresh folder
//    exactly one proceeds; the other is refused naming the holder. The lock is removed at exit.
//  - A non-empty folder is refused unless --overwrite; with it, the files a previous run of the
//    same command left (`stale`, e.g. frame_* of a longer render) and temporaries of a killed
//    run are removed first, and said so, so that the folder holds only this run's output.
//  - A run that fails removes the folders it created itself if they are still empty.
#pragma once

#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace px {

class OutputDir {
 public:
  // Predicate on a file name (no folder): was it written by this command in an earlier run?
  using StaleFilter = std::function<bool(std::string_view)>;

  // Creates `dir` if needed and claims it. Throws std::runtime_error if another run holds it,
  // if it is not a folder, or if it holds files and !overwrite.
  OutputDir(const std::string& dir, bool overwrite, const StaleFilter& stale = {});
  ~OutputDir();
  OutputDir(const OutputDir&) = delete;
  OutputDir& operator=(const OutputDir&) = delete;

  const std::string& path() const { return dir_; }
  std::string file(const std::string& name) const;

  static constexpr const char* kLockName = ".parallax.lock";

 private:
  std::string dir_;
  std::string lock_;
  bool locked_ = false;
  std::vector<std::string> created_;  // outermost first
};

// True for frame_NNNN_{left,right,stereo}.{exr,png} and frame_NNNN_{left,right}_{albedo,normal}.exr
// (--aov): the files `render` writes.
bool is_render_frame_file(std::string_view name);

}  // namespace px
