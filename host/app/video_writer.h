// render --video: the frames piped, as raw RGBA, into the ffmpeg program (Debian package
// ffmpeg), which encodes them with H.264. Like every output, the file appears under its name
// only when complete: ffmpeg writes a hidden temporary next to it, renamed at commit().
#pragma once

#include <cstdint>
#include <string>
#include <sys/types.h>
#include <vector>

namespace px {

class VideoWriter {
 public:
  // Starts ffmpeg for `width` x `height` RGBA frames at `fps`. Throws std::runtime_error when
  // ffmpeg is not installed (naming the package), std::invalid_argument for a file name that
  // is not .mp4 / .mkv / .mov or whose folder does not exist.
  VideoWriter(std::string path, unsigned width, unsigned height, float fps);
  // Uncommitted: stops ffmpeg and removes the temporary file.
  ~VideoWriter();
  VideoWriter(const VideoWriter&) = delete;
  VideoWriter& operator=(const VideoWriter&) = delete;

  // One frame, width * height * 4 bytes, rows top to bottom. Throws std::runtime_error if
  // ffmpeg has stopped.
  void write_frame(const std::vector<std::uint8_t>& rgba);
  // Ends the stream, waits for ffmpeg and renames the file into place; throws if ffmpeg failed.
  void commit();
  const std::string& path() const { return path_; }

  // The ffmpeg executable on $PATH, "" if there is none.
  static std::string find_ffmpeg();

 private:
  void stop_encoder(bool kill_it);
  std::string path_, tmp_;
  unsigned width_, height_;
  pid_t pid_ = -1;
  int pipe_fd_ = -1;
  int slot_ = -1;  // interrupt-handler registration of tmp_
};

}  // namespace px
