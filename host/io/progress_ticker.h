// "Still working" lines for a long step of a start (parsing a large scene, building its BVH,
// uploading it): a step that finishes within `after` says nothing more than it already does;
// past that, a line every `every` says what is running and for how long, so a 10M-triangle
// start is never a silent minute. A background thread writes the lines; the destructor stops it
// at once (the step's own completion line follows).
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>

namespace px {

class ProgressTicker {
 public:
  struct Options {
    std::chrono::milliseconds after{3000};  // silent for steps shorter than this
    std::chrono::milliseconds every{5000};  // then a line this often
    std::FILE* out = stderr;
  };

  // `what`: the line's text, e.g. "[bvh] building the BVH"; a line reads "<what>: 8 s so far".
  // An empty `what` ticks nothing (a quiet start).
  explicit ProgressTicker(std::string what) : ProgressTicker(std::move(what), Options{}) {}
  ProgressTicker(std::string what, Options options);
  ~ProgressTicker();
  ProgressTicker(const ProgressTicker&) = delete;
  ProgressTicker& operator=(const ProgressTicker&) = delete;

  // Lines written so far.
  int lines() const;

 private:
  void run();

  const std::string what_;
  const Options options_;
  const std::chrono::steady_clock::time_point start_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  int lines_ = 0;
  std::thread thread_;
};

}  // namespace px
