#include "io/interrupt.h"

#include <atomic>
#include <csignal>
#include <cstring>

#include <unistd.h>

namespace px {
namespace {

constexpr std::size_t kPathMax = 4096;
constexpr int kMaxDirs = 8;

struct Slot {
  char path[kPathMax];
  volatile std::sig_atomic_t set;
};

volatile std::sig_atomic_t g_signal = 0;
constexpr int kMaxPartials = 8;
Slot g_partials[kMaxPartials]{};
// Which partial slots are taken: the frame loop's files and the cache writes
// (background_writes.h) register from two threads.
std::atomic<bool> g_partial_taken[kMaxPartials]{};
Slot g_lock{};
Slot g_dirs[kMaxDirs]{};
std::atomic<bool> g_installed{false};

bool fill(Slot& slot, const char* path) {
  slot.set = 0;
  std::atomic_signal_fence(std::memory_order_seq_cst);
  const std::size_t n = std::strlen(path);
  if (n >= kPathMax) return false;
  std::memcpy(slot.path, path, n + 1);
  std::atomic_signal_fence(std::memory_order_seq_cst);
  slot.set = 1;
  return true;
}

void say(const char* text) {
  // write(2) is async-signal-safe; a short or failed write of a message is not worth handling.
  const ssize_t ignored = ::write(STDERR_FILENO, text, std::strlen(text));
  (void)ignored;
}

extern "C" void on_interrupt(int sig) {
  if (g_signal == 0) {
    g_signal = sig;
    say("\n[interrupt] finishing the work in flight, then writing what is done "
        "(interrupt again to stop at once)\n");
    return;
  }
  for (const Slot& s : g_partials)
    if (s.set) ::unlink(s.path);
  if (g_lock.set) ::unlink(g_lock.path);
  for (int i = kMaxDirs - 1; i >= 0; --i)
    if (g_dirs[i].set) ::rmdir(g_dirs[i].path);
  say("\n[interrupt] stopped at once; files already complete were kept, the one being written was removed\n");
  ::_exit(128 + g_signal);
}

}  // namespace

void install_interrupt_handlers() {
  if (g_installed.exchange(true)) return;
  struct sigaction sa {};
  sa.sa_handler = on_interrupt;
  sigemptyset(&sa.sa_mask);
  // Restart interrupted system calls: the first signal only sets a flag the program polls.
  sa.sa_flags = SA_RESTART;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

int interrupt_signal() { return g_signal; }
int interrupt_exit_code() { return g_signal ? 128 + g_signal : 0; }
const char* interrupt_signal_name() {
  switch (g_signal) {
    case SIGINT: return "SIGINT";
    case SIGTERM: return "SIGTERM";
    case 0: return "none";
  }
  return "a signal";
}

// A thread claims a slot before filling it; the handler only reads.
int register_partial_file(const char* path) {
  for (int i = 0; i < kMaxPartials; ++i)
    if (!g_partial_taken[i].exchange(true)) {
      if (fill(g_partials[i], path)) return i;
      g_partial_taken[i].store(false);
      return -1;
    }
  return -1;
}
void unregister_partial_file(int slot) {
  if (slot < 0 || slot >= kMaxPartials) return;
  g_partials[slot].set = 0;
  g_partial_taken[slot].store(false);
}
void register_lock_file(const char* path) { fill(g_lock, path); }
void unregister_lock_file() { g_lock.set = 0; }
void register_created_dir(const char* path) {
  for (Slot& s : g_dirs)
    if (!s.set) {
      fill(s, path);
      return;
    }
}
void unregister_created_dirs() {
  for (Slot& s : g_dirs) s.set = 0;
}

void simulate_interrupt_for_testing(int signal) {
  if (g_signal == 0) g_signal = signal;
}

}  // namespace px
