// Output files appear complete or not at all. Every file parallax writes (images, reports,
// timelines) goes through write_file_atomic: the bytes go to a hidden temporary file in the
// same folder (same file system, so the final rename is atomic), every write() and the close()
// are checked, and only a complete file is renamed to its final name. A full disk, a quota or a
// second Ctrl-C therefore never leaves a truncated file under a name a user would open.
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>

namespace px {

// A file could not be written; what() names the file and the reason (strerror).
struct WriteError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A file written in pieces (a report streamed frame by frame) with the same guarantee: it
// appears under `path` only at commit(); destroyed uncommitted, it leaves nothing. Creating it
// checks at once that the file can be written (a bad --report path fails before rendering).
class AtomicFileWriter {
 public:
  explicit AtomicFileWriter(std::string path);  // throws WriteError
  ~AtomicFileWriter();
  AtomicFileWriter(const AtomicFileWriter&) = delete;
  AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;

  void write(std::string_view bytes);  // throws WriteError (and removes the temporary file)
  void commit();                       // close + rename; throws WriteError
  const std::string& path() const { return path_; }

 private:
  [[noreturn]] void fail(const char* step, int err);
  std::string path_, tmp_;
  int fd_ = -1;
  int slot_ = -1;  // interrupt-handler registration of tmp_
};

// Writes `bytes` to `path` atomically (see above). Throws WriteError; on failure neither the
// temporary file nor a new file under `path` remains (an existing file at `path` is untouched).
void write_file_atomic(const std::string& path, std::string_view bytes);

// The temporary name write_file_atomic uses for `path` in this process:
// DIR/.NAME.PID.partial. Hidden, so a glob for frame_* never matches it.
std::string partial_path_for(const std::string& path);
// True for a file name (no folder) of that form, e.g. to clean up after a killed run.
bool is_partial_name(std::string_view filename);

}  // namespace px
