#include "io/atomic_file.h"

#include "io/interrupt.h"

#include <cerrno>
#include <cstring>
#include <filesystem>

#include <fcntl.h>
#include <unistd.h>

namespace px {

namespace fs = std::filesystem;

std::string partial_path_for(const std::string& path) {
  const fs::path p(path);
  return (p.parent_path() / ("." + p.filename().string() + "." + std::to_string(::getpid()) + ".partial")).string();
}

bool is_partial_name(std::string_view filename) {
  constexpr std::string_view suffix = ".partial";
  return filename.size() > suffix.size() + 1 && filename.front() == '.' &&
         filename.substr(filename.size() - suffix.size()) == suffix;
}

void write_file_atomic(const std::string& path, std::string_view bytes) {
  const std::string tmp = partial_path_for(path);
  auto fail = [&](const char* step, int err) {
    ::unlink(tmp.c_str());
    unregister_partial_file();
    throw WriteError("cannot write " + path + ": " + step + ": " + std::strerror(err));
  };
  // Registered before it exists, so that a second Ctrl-C between open() and rename() removes it.
  register_partial_file(tmp.c_str());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd < 0) {
    const int err = errno;
    unregister_partial_file();
    throw WriteError("cannot write " + path + ": cannot create " + tmp + ": " + std::strerror(err));
  }
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = n < 0 ? errno : EIO;
      ::close(fd);
      fail("write", err);
    }
    done += static_cast<std::size_t>(n);
  }
  // close() is where some file systems (NFS, FUSE, quotas) report a failed write; never retried
  // (the descriptor is gone either way).
  if (::close(fd) != 0) fail("close", errno);
  if (::rename(tmp.c_str(), path.c_str()) != 0) fail("rename", errno);
  unregister_partial_file();
}

}  // namespace px
