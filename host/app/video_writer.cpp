#include "app/video_writer.h"

#include "io/atomic_file.h"
#include "io/interrupt.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <spawn.h>
#include <stdexcept>
#include <sys/wait.h>
#include <unistd.h>

extern char** environ;

namespace px {
namespace {

namespace fs = std::filesystem;

// ffmpeg's name for the container of a file extension ("" if not supported).
std::string container_for(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".mp4") return "mp4";
  if (ext == ".mkv") return "matroska";
  if (ext == ".mov") return "mov";
  return "";
}

}  // namespace

std::string VideoWriter::find_ffmpeg() {
  const char* path_env = std::getenv("PATH");
  std::string dirs = path_env ? path_env : "";
  std::size_t begin = 0;
  while (begin <= dirs.size()) {
    const std::size_t end = std::min(dirs.find(':', begin), dirs.size());
    const std::string dir = dirs.substr(begin, end - begin);
    const std::string candidate = (dir.empty() ? std::string(".") : dir) + "/ffmpeg";
    if (::access(candidate.c_str(), X_OK) == 0 && fs::is_regular_file(candidate)) return candidate;
    begin = end + 1;
  }
  return "";
}

VideoWriter::VideoWriter(std::string path, unsigned width, unsigned height, float fps)
    : path_(std::move(path)), tmp_(partial_path_for(path_)), width_(width), height_(height) {
  const std::string container = container_for(path_);
  if (container.empty()) throw std::invalid_argument("--video " + path_ + ": the file must end in .mp4, .mkv or .mov");
  const fs::path parent = fs::path(path_).parent_path();
  if (!parent.empty() && !fs::is_directory(parent))
    throw std::invalid_argument("--video " + path_ + ": folder " + parent.string() + " does not exist");
  if (!(fps > 0.0f)) throw std::invalid_argument("--fps must be positive");
  const std::string ffmpeg = find_ffmpeg();
  if (ffmpeg.empty())
    throw std::runtime_error(
        "--video needs the ffmpeg program, which is not on PATH: install the Debian package "
        "ffmpeg (apt-get install ffmpeg)");

  // H.264 in yuv420p wants even sizes: pad by a pixel where needed.
  char size[32], rate[32];
  std::snprintf(size, sizeof size, "%ux%u", width, height);
  std::snprintf(rate, sizeof rate, "%g", double(fps));
  std::vector<std::string> args = {ffmpeg,
                                   "-hide_banner",
                                   "-loglevel",
                                   "error",
                                   "-y",
                                   "-f",
                                   "rawvideo",
                                   "-pix_fmt",
                                   "rgba",
                                   "-s",
                                   size,
                                   "-r",
                                   rate,
                                   "-i",
                                   "pipe:0",
                                   "-vf",
                                   "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                                   "-c:v",
                                   "libx264",
                                   "-preset",
                                   "veryfast",
                                   "-crf",
                                   "18",
                                   "-pix_fmt",
                                   "yuv420p",
                                   "-f",
                                   container,
                                   tmp_};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  int fds[2];
  if (::pipe(fds) != 0) throw std::runtime_error(std::string("--video: pipe: ") + std::strerror(errno));
  // A dead ffmpeg must fail a write with EPIPE, not kill parallax.
  std::signal(SIGPIPE, SIG_IGN);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[0], STDIN_FILENO);
  posix_spawn_file_actions_addclose(&actions, fds[0]);
  posix_spawn_file_actions_addclose(&actions, fds[1]);
  // Its own process group: Ctrl-C in the terminal reaches parallax only, which then finishes
  // the frame in flight and closes the stream, so the video holds every finished frame.
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP);
  posix_spawnattr_setpgroup(&attr, 0);
  const int rc = posix_spawn(&pid_, ffmpeg.c_str(), &actions, &attr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  ::close(fds[0]);
  if (rc != 0) {
    ::close(fds[1]);
    pid_ = -1;
    throw std::runtime_error("--video: cannot start " + ffmpeg + ": " + std::strerror(rc));
  }
  pipe_fd_ = fds[1];
  slot_ = register_partial_file(tmp_.c_str());
}

VideoWriter::~VideoWriter() {
  if (pid_ > 0) {
    stop_encoder(true);
    ::unlink(tmp_.c_str());
  }
  unregister_partial_file(slot_);
}

void VideoWriter::stop_encoder(bool kill_it) {
  if (pipe_fd_ >= 0) ::close(pipe_fd_);
  pipe_fd_ = -1;
  if (pid_ <= 0) return;
  if (kill_it) ::kill(pid_, SIGKILL);
  int status = 0;
  while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {}
  pid_ = -1;
  if (!kill_it && !(WIFEXITED(status) && WEXITSTATUS(status) == 0)) {
    ::unlink(tmp_.c_str());
    throw std::runtime_error("--video " + path_ + ": ffmpeg failed (" +
                             (WIFEXITED(status) ? "exit " + std::to_string(WEXITSTATUS(status))
                                                : "signal " + std::to_string(WTERMSIG(status))) +
                             "; its messages are above)");
  }
}

void VideoWriter::write_frame(const std::vector<std::uint8_t>& rgba) {
  if (rgba.size() != std::size_t(width_) * height_ * 4) throw std::invalid_argument("--video: frame of the wrong size");
  if (pipe_fd_ < 0) throw std::runtime_error("--video " + path_ + ": the stream is closed");
  const std::uint8_t* p = rgba.data();
  std::size_t left = rgba.size();
  while (left > 0) {
    const ssize_t n = ::write(pipe_fd_, p, left);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = errno;
      stop_encoder(true);
      ::unlink(tmp_.c_str());
      throw std::runtime_error("--video " + path_ + ": ffmpeg stopped reading frames (" + std::strerror(err) +
                               "; its messages are above)");
    }
    p += n;
    left -= static_cast<std::size_t>(n);
  }
}

void VideoWriter::commit() {
  stop_encoder(false);
  std::error_code ec;
  fs::rename(tmp_, path_, ec);
  if (ec) {
    ::unlink(tmp_.c_str());
    throw std::runtime_error("--video: cannot rename the finished video to " + path_ + ": " + ec.message());
  }
  unregister_partial_file(slot_);
  slot_ = -1;
}

}  // namespace px
