#include "app/output_dir.h"

#include "io/atomic_file.h"
#include "io/interrupt.h"

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace px {

namespace fs = std::filesystem;

namespace {

// What the lock file says about its holder, for the refusal message.
std::string describe_holder(const std::string& lock) {
  std::ifstream in(lock);
  long pid = 0;
  std::string word;
  if (!(in >> word >> pid) || word != "pid" || pid <= 0) return "another parallax run";
  std::string text = "another parallax run (pid " + std::to_string(pid) + ")";
  if (::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH)
    text += ", which is no longer running: it was killed or crashed; delete " + lock + " to use the folder again";
  return text;
}

}  // namespace

bool is_render_frame_file(std::string_view name) {
  // frame_[0-9]{4,}_(left|right|stereo).(exr|png), or an auxiliary image (render --aov):
  // frame_[0-9]{4,}_(left|right)_(albedo|normal).exr
  constexpr std::string_view prefix = "frame_";
  if (name.substr(0, prefix.size()) != prefix) return false;
  name.remove_prefix(prefix.size());
  std::size_t digits = 0;
  while (digits < name.size() && name[digits] >= '0' && name[digits] <= '9') ++digits;
  if (digits < 4 || digits >= name.size() || name[digits] != '_') return false;
  name.remove_prefix(digits + 1);
  for (std::string_view eye : {"left", "right", "stereo"})
    for (std::string_view ext : {".exr", ".png"})
      if (name.size() == eye.size() + ext.size() && name.substr(0, eye.size()) == eye && name.substr(eye.size()) == ext)
        return true;
  for (std::string_view eye : {"left_", "right_"})
    for (std::string_view aov : {"albedo.exr", "normal.exr"})
      if (name.size() == eye.size() + aov.size() && name.substr(0, eye.size()) == eye && name.substr(eye.size()) == aov)
        return true;
  return false;
}

OutputDir::OutputDir(const std::string& dir, bool overwrite, const StaleFilter& stale) : dir_(dir) {
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw std::runtime_error("output path " + dir + " exists and is not a directory");
  // Create the missing folders one by one, remembering which are ours (removed again on failure).
  {
    std::vector<fs::path> missing;
    for (fs::path p = fs::path(dir); !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
      missing.push_back(p);
      if (p == p.parent_path()) break;
    }
    for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
      if (::mkdir(it->c_str(), 0777) != 0) {
        if (errno == EEXIST && fs::is_directory(*it, ec)) continue;  // another run made it meanwhile
        const int err = errno;
        for (auto c = created_.rbegin(); c != created_.rend(); ++c) ::rmdir(c->c_str());
        unregister_created_dirs();
        throw std::runtime_error("cannot create output directory " + it->string() + ": " + std::strerror(err));
      }
      created_.push_back(it->string());
      register_created_dir(it->c_str());
    }
  }
  auto give_up = [&](const std::string& message) {
    if (locked_) {
      ::unlink(lock_.c_str());
      unregister_lock_file();
      locked_ = false;
    }
    for (auto c = created_.rbegin(); c != created_.rend(); ++c) ::rmdir(c->c_str());
    unregister_created_dirs();
    throw std::runtime_error(message);
  };

  lock_ = (fs::path(dir) / kLockName).string();
  const int fd = ::open(lock_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    if (errno == EEXIST)
      give_up("output directory " + dir + " is in use by " + describe_holder(lock_) +
              "; wait for it to finish or choose another --out");
    give_up("cannot claim output directory " + dir + ": cannot create " + lock_ + ": " + std::strerror(errno));
  }
  locked_ = true;
  register_lock_file(lock_.c_str());
  const std::string holder = "pid " + std::to_string(::getpid()) + "\n";
  const bool wrote = ::write(fd, holder.data(), holder.size()) == static_cast<ssize_t>(holder.size());
  const bool closed = ::close(fd) == 0;
  if (!wrote || !closed) give_up("cannot claim output directory " + dir + ": cannot write " + lock_);

  // The emptiness check, now that no other run can start writing here.
  std::vector<fs::path> entries;
  for (auto it = fs::directory_iterator(dir, ec); !ec && it != fs::directory_iterator(); it.increment(ec))
    if (it->path().filename() != kLockName) entries.push_back(it->path());
  if (ec) give_up("cannot list output directory " + dir + ": " + ec.message());
  if (entries.empty()) return;
  if (!overwrite)
    give_up("output directory " + dir + " is not empty (" + std::to_string(entries.size()) +
            " entries); pass --overwrite to replace its files, or choose another --out");
  std::size_t removed = 0, kept = 0;
  for (const fs::path& p : entries) {
    const std::string name = p.filename().string();
    if (is_partial_name(name) || (stale && stale(name) && fs::is_regular_file(p, ec))) {
      if (!fs::remove(p, ec) || ec) give_up("--overwrite: cannot remove " + p.string() + ": " + ec.message());
      ++removed;
    } else {
      ++kept;
    }
  }
  if (removed)
    std::fprintf(stderr, "[out] --overwrite: removed %zu file(s) of an earlier run from %s\n", removed, dir.c_str());
  if (kept)
    std::fprintf(stderr, "[out] %s holds %zu other entr%s: files of the same name as this run's will be replaced\n",
                 dir.c_str(), kept, kept == 1 ? "y" : "ies");
}

OutputDir::~OutputDir() {
  if (locked_) {
    ::unlink(lock_.c_str());
    unregister_lock_file();
  }
  // Folders this run created and left empty (a run that failed before writing anything) go
  // again; rmdir refuses a non-empty folder, which is exactly the condition wanted.
  for (auto c = created_.rbegin(); c != created_.rend(); ++c) ::rmdir(c->c_str());
  unregister_created_dirs();
}

std::string OutputDir::file(const std::string& name) const { return (fs::path(dir_) / name).string(); }

}  // namespace px
