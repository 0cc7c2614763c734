#include "cl/pocl_launch_guard.h"

#include "cl/cl_error.h"
#include "io/environment.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>

namespace px {

namespace {

// A launch the guard may have to wait for: its event, and the queue and context it ran on
// (events of another context cannot be in a wait list: those are waited for on the host).
struct RecordedLaunch {
  cl_context context = nullptr;
  cl_command_queue queue = nullptr;
  cl::Event event;
};

}  // namespace

struct PoclKernelLaunches {
  // The widest global size launched in this process. PoCL's entries outlive contexts and
  // programs, so this survives forget_context (a later device set meets the same entries).
  std::size_t widest = 0;
  std::vector<RecordedLaunch> last;  // the last launch on each queue
  RecordedLaunch widening;           // the launch that set `widest`, until it is known complete
};

namespace {

struct Registry {
  std::mutex mutex;
  std::map<cl_program, std::pair<cl_context, std::string>> programs;  // guarded programs
  // Keyed by program identity, kernel name and local size: the granularity of PoCL's entries.
  std::map<std::string, PoclKernelLaunches> kernels;
  long widening_launches = 0;
};

// Never destroyed: launches may run during static destruction, and the events it holds are
// released by forget_context while their contexts are alive.
Registry& registry() {
  static Registry* r = new Registry;
  return *r;
}

bool finished(const cl::Event& e) {
  cl_int status = CL_QUEUED;
  PX_CL_CHECK(clGetEventInfo(e(), CL_EVENT_COMMAND_EXECUTION_STATUS, sizeof status, &status, nullptr));
  return status <= CL_COMPLETE;  // complete, or failed (a negative status)
}

}  // namespace

bool PoclLaunchGuard::enabled() { return environment().pocl_launch_guard; }

void PoclLaunchGuard::register_program(cl_context context, cl_program program, const std::string& identity) {
  auto& r = registry();
  std::lock_guard<std::mutex> lock(r.mutex);
  r.programs[program] = {context, identity};
}

void PoclLaunchGuard::forget_context(cl_context context) {
  auto& r = registry();
  std::lock_guard<std::mutex> lock(r.mutex);
  for (auto it = r.programs.begin(); it != r.programs.end();)
    it = it->second.first == context ? r.programs.erase(it) : std::next(it);
  for (auto& [key, k] : r.kernels) {
    // A set torn down with launches in flight: they finish first, so that no later set's launch
    // of the kernel overlaps with one the guard no longer knows.
    for (const auto& l : k.last)
      if (l.context == context && l.event() && !finished(l.event)) l.event.wait();
    k.last.erase(
        std::remove_if(k.last.begin(), k.last.end(), [&](const RecordedLaunch& l) { return l.context == context; }),
        k.last.end());
    if (k.widening.context == context) k.widening = RecordedLaunch{};
    // PoCL evicts unused entries once it holds 128: the widest one may be gone by the next set.
    // Starting over costs that set one ordered launch per kernel and never under-counts.
    k.widest = 0;
  }
}

long PoclLaunchGuard::widening_launches() {
  auto& r = registry();
  std::lock_guard<std::mutex> lock(r.mutex);
  return r.widening_launches;
}

// The lock is held until the launch is recorded: the guard sees launches in host order.
PoclLaunchGuard::PoclLaunchGuard(const cl::CommandQueue& queue, const cl::Kernel& kernel, std::size_t global,
                                 std::size_t local, std::vector<cl::Event>& waits)
    : lock_(registry().mutex) {
  auto& r = registry();
  if (r.programs.empty()) return;
  cl_program program = nullptr;
  PX_CL_CHECK(clGetKernelInfo(kernel(), CL_KERNEL_PROGRAM, sizeof program, &program, nullptr));
  auto p = r.programs.find(program);
  if (p == r.programs.end()) return;  // not built by a guarded device set

  kernel_ =
      &r.kernels[p->second.second + "|" + kernel.getInfo<CL_KERNEL_FUNCTION_NAME>() + "|" + std::to_string(local)];
  queue_ = queue();
  context_ = p->second.first;
  global_ = global;
  widens_ = global > kernel_->widest;
  // A launch on the same queue is ordered by the in-order queue already.
  auto wait_for = [&](const RecordedLaunch& l) {
    if (!l.event() || l.queue == queue_ || finished(l.event)) return;
    if (l.context == context_) {
      // Waiting on another queue's event needs that queue flushed (OpenCL 1.2, 5.13).
      PX_CL_CHECK(clFlush(l.queue));
      waits.push_back(l.event);
    } else {
      // Two device sets at once (the entries are process-wide): wait on the host, holding the
      // lock, so every launch in the process waits too. Rare: sets are made one after another.
      l.event.wait();
    }
  };
  if (widens_) {
    for (const auto& l : kernel_->last) wait_for(l);
  } else if (kernel_->widening.event()) {
    if (finished(kernel_->widening.event))
      kernel_->widening = RecordedLaunch{};
    else
      wait_for(kernel_->widening);
  }
}

void PoclLaunchGuard::done(const cl::Event& launched) {
  if (!kernel_) return;
  auto slot = std::find_if(kernel_->last.begin(), kernel_->last.end(),
                           [&](const RecordedLaunch& l) { return l.queue == queue_; });
  if (slot == kernel_->last.end())
    slot = kernel_->last.insert(kernel_->last.end(), RecordedLaunch{context_, queue_, {}});
  slot->event = launched;
  if (widens_) {
    kernel_->widest = global_;
    kernel_->widening = RecordedLaunch{context_, queue_, launched};
    ++registry().widening_launches;
    // Launches on other queues will wait for this one: make sure it is submitted.
    PX_CL_CHECK(clFlush(queue_));
  }
}

}  // namespace px
