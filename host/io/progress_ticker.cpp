#include "io/progress_ticker.h"

namespace px {

ProgressTicker::ProgressTicker(std::string what, Options options)
    : what_(std::move(what)), options_(options), start_(std::chrono::steady_clock::now()) {
  if (!what_.empty() && options_.out) thread_ = std::thread([this] { run(); });
}

ProgressTicker::~ProgressTicker() {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

int ProgressTicker::lines() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return lines_;
}

void ProgressTicker::run() {
  std::unique_lock<std::mutex> lock(mutex_);
  auto next = start_ + options_.after;
  for (;;) {
    if (wake_.wait_until(lock, next, [this] { return stop_; })) return;
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    std::fprintf(options_.out, "%s: %.0f s so far\n", what_.c_str(), s);
    std::fflush(options_.out);
    ++lines_;
    next += options_.every;
  }
}

}  // namespace px
