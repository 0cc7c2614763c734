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
  std::string name(1, '.');
  name.append(p.filename().string()).append(1, '.').append(std::to_string(::getpid())).append(".partial");
  return (p.parent_path() / name).string();
}

bool is_partial_name(std::string_view filename) {
  constexpr std::string_view suffix = ".partial";
  return filename.size() > suffix.size() + 1 && filename.front() == '.' &&
         filename.substr(filename.size() - suffix.size()) == suffix;
}

AtomicFileWriter::AtomicFileWriter(std::string path) : path_(std::move(path)), tmp_(partial_path_for(path_)) {
  // Registered before it exists, so that a second Ctrl-C between open() and rename() removes it.
  slot_ = register_partial_file(tmp_.c_str());
  fd_ = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd_ < 0) {
    const int err = errno;
    unregister_partial_file(slot_);
    slot_ = -1;
    throw WriteError("cannot write " + path_ + ": cannot create " + tmp_ + ": " + std::strerror(err));
  }
}

AtomicFileWriter::~AtomicFileWriter() {
  if (fd_ >= 0) ::close(fd_);
  if (slot_ >= 0) {
    ::unlink(tmp_.c_str());
    unregister_partial_file(slot_);
  }
}

void AtomicFileWriter::fail(const char* step, int err) {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  ::unlink(tmp_.c_str());
  unregister_partial_file(slot_);
  slot_ = -1;
  throw WriteError("cannot write " + path_ + ": " + step + ": " + std::strerror(err));
}

void AtomicFileWriter::write(std::string_view bytes) {
  if (fd_ < 0) throw WriteError("cannot write " + path_ + ": already closed");
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) fail("write", n < 0 ? errno : EIO);
    done += static_cast<std::size_t>(n);
  }
}

void AtomicFileWriter::commit() {
  if (fd_ < 0) throw WriteError("cannot write " + path_ + ": already closed");
  // close() is where some file systems (NFS, FUSE, quotas) report a failed write; never retried
  // (the descriptor is gone either way).
  const int rc = ::close(fd_);
  fd_ = -1;
  if (rc != 0) fail("close", errno);
  if (::rename(tmp_.c_str(), path_.c_str()) != 0) fail("rename", errno);
  unregister_partial_file(slot_);
  slot_ = -1;
}

void write_file_atomic(const std::string& path, std::string_view bytes) {
  AtomicFileWriter out(path);
  out.write(bytes);
  out.commit();
}

}  // namespace px
