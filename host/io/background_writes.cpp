#include "io/background_writes.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>

namespace px {

BackgroundWrites::~BackgroundWrites() { wait(); }

BackgroundWrites::Ticket BackgroundWrites::submit(Job job, Start start) {
  std::lock_guard<std::mutex> lock(mutex_);
  const Ticket ticket = next_++;
  queue_.push_back({ticket, std::move(job), start});
  if (!thread_.joinable()) {
    stop_ = false;
    thread_ = std::thread([this] { run(); });
  }
  changed_.notify_all();
  return ticket;
}

void BackgroundWrites::first_frame_on_its_way() {
  std::lock_guard<std::mutex> lock(mutex_);
  gate_open_ = true;
  changed_.notify_all();
}

void BackgroundWrites::wait_for(Ticket ticket) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (ticket >= next_ || done_ > ticket) return;
  // A held job before it would hold it too: the jobs up to this one may run, not those after it
  // (the device layout's write, queued later, still waits for the first frame).
  run_upto_ = std::max(run_upto_, ticket + 1);
  changed_.notify_all();
  changed_.wait(lock, [&] { return done_ > ticket; });
}

void BackgroundWrites::wait() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!thread_.joinable()) return;
    stop_ = true;  // run every job left, held or not, then end
    changed_.notify_all();
  }
  thread_.join();
  std::lock_guard<std::mutex> lock(mutex_);
  thread_ = std::thread();
}

double BackgroundWrites::busy_ms() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return busy_ms_;
}

bool BackgroundWrites::any() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return next_ > 0;
}

void BackgroundWrites::run() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    changed_.wait(lock, [&] {
      return stop_ || (!queue_.empty() &&
                       (queue_.front().start == Start::Now || gate_open_ || queue_.front().ticket < run_upto_));
    });
    if (queue_.empty()) return;  // stop_ and nothing left
    Entry entry = std::move(queue_.front());
    queue_.pop_front();
    lock.unlock();
    const auto t0 = std::chrono::steady_clock::now();
    try {
      entry.job();
    } catch (const std::exception& e) {  // a job says what failed itself; this is a last resort
      std::fprintf(stderr, "[cache] warning: a cache write failed (%s)\n", e.what());
    } catch (...) {
      std::fprintf(stderr, "[cache] warning: a cache write failed\n");
    }
    entry.job = nullptr;  // its data goes now, not with the next job
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    lock.lock();
    busy_ms_ += ms;
    done_ = entry.ticket + 1;
    changed_.notify_all();
  }
}

}  // namespace px
