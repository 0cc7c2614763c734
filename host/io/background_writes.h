// Cache files written on a thread of their own, so that a start does not wait for what only the
// next start reads (the BVH cache, the device layout cache: docs/measurements.md, "Cache writes
// off the critical path"). Jobs run one at a time in the order they came. A job submitted with
// Start::AfterFirstFrame waits until first_frame_on_its_way() (render calls it as it submits its
// first frame, which needs the cores for the kernels' compilation before anything else), or
// until wait(). A job that must run now (its data is held for it, and freed after it) starts at
// once: Start::Now.
//
// The process waits for every job before it exits: wait() (render's summary reports the time),
// else the destructor, so an error or an interrupt that unwinds the start still leaves every
// file complete or absent (the files go through AtomicFileWriter, whose temporary a second
// Ctrl-C removes). A job reports its own failures (a cache never fails a run) and returns the
// milliseconds it took.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>

namespace px {

class BackgroundWrites {
 public:
  enum class Start { Now, AfterFirstFrame };
  using Job = std::function<void()>;
  // A submitted job, to wait for (done()).
  using Ticket = std::size_t;

  BackgroundWrites() = default;
  BackgroundWrites(const BackgroundWrites&) = delete;
  BackgroundWrites& operator=(const BackgroundWrites&) = delete;
  ~BackgroundWrites();  // wait()

  Ticket submit(Job job, Start start);
  // Lets the jobs submitted with Start::AfterFirstFrame run.
  void first_frame_on_its_way();
  // Until job `ticket` has run (it runs now if it was held for the first frame).
  void wait_for(Ticket ticket);
  // Until every job has run; the thread is gone afterwards (a later submit starts another).
  void wait();
  // Milliseconds the jobs that ended took, all of them together (the writer thread's time).
  double busy_ms() const;
  // Whether any job was submitted.
  bool any() const;

 private:
  void run();
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  struct Entry {
    Ticket ticket;
    Job job;
    Start start;
  };
  std::deque<Entry> queue_;
  std::thread thread_;
  bool gate_open_ = false, stop_ = false;
  Ticket next_ = 0, done_ = 0;  // tickets below done_ have run (jobs run in order)
  Ticket run_upto_ = 0;         // held jobs below it run before the first frame (wait_for)
  double busy_ms_ = 0.0;
};

}  // namespace px
