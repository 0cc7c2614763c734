// Work split into parts, one per core, for the start's single passes over a large scene (the
// triangles of a large glTF primitive, the BVH's leaf triangles and build primitives): a pass of a
// few hundred milliseconds over millions of items, where a thread pool would only add setup.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <system_error>
#include <thread>
#include <vector>

#include <sys/mman.h>
#include <unistd.h>

namespace px {

// How many parts a pass over `count` items is split into: 1 below `from` items, else one per
// core (at most 8: these passes are bound by memory beyond that).
inline unsigned parallel_parts(std::size_t count, std::size_t from) {
  if (count < from) return 1u;
  return std::clamp(std::thread::hardware_concurrency(), 1u, 8u);
}

// The items [begin, end) of part `part` of `parts` over `count` items: contiguous, in order.
struct PartRange {
  std::size_t begin = 0, end = 0;
};
inline PartRange part_range(std::size_t count, unsigned part, unsigned parts) {
  return {count * part / parts, count * (part + 1) / parts};
}

// fn(part) for every part in [0, parts), part 0 on the calling thread, and any part a thread
// could not be started for (the system out of threads) after it. An exception of any part is
// rethrown once every part has ended (the first part's that threw).
template <typename Fn>
void run_parts(unsigned parts, const Fn& fn) {
  std::vector<std::exception_ptr> failures(parts);
  const auto run = [&](unsigned part) {
    try {
      fn(part);
    } catch (...) {
      failures[part] = std::current_exception();
    }
  };
  std::vector<std::thread> others;
  others.reserve(parts > 0 ? parts - 1 : 0);
  unsigned started = 1;
  try {
    for (; started < parts; ++started) others.emplace_back(run, started);
  } catch (const std::system_error&) {}
  if (parts > 0) run(0);
  for (unsigned part = started; part < parts; ++part) run(part);
  for (std::thread& t : others) t.join();
  for (const std::exception_ptr& f : failures)
    if (f) std::rethrow_exception(f);
}

// Faults in the whole pages of `n` elements' storage at `p` (allocated, not yet written) on the
// calling thread, so that parts writing their own ranges clear fresh pages side by side instead
// of one thread at a time. Contents are not touched; a kernel without MADV_POPULATE_WRITE
// (before Linux 5.14) leaves the pages to the first write.
template <typename T>
void populate_for_writing(T* p, std::size_t n) {
#ifdef MADV_POPULATE_WRITE
  const auto page = static_cast<std::uintptr_t>(sysconf(_SC_PAGESIZE));
  const auto begin = (reinterpret_cast<std::uintptr_t>(p) + page - 1) / page * page;
  const auto end = reinterpret_cast<std::uintptr_t>(p + n) / page * page;
  if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_POPULATE_WRITE);
#else
  (void)p;
  (void)n;
#endif
}

// Grows the empty vector `v` to `n` elements, the fresh pages of its first `touched` (all by
// default) faulted in by `parts` parts side by side first: the resize then only writes them (with
// an uninitialising allocator, not even that), and each part's later writes find them resident.
template <typename Vector>
void resize_in_parts(Vector& v, std::size_t n, unsigned parts, std::size_t touched) {
  v.reserve(n);
  touched = std::min(touched, n);
  run_parts(parts, [&](unsigned part) {
    const PartRange r = part_range(touched, part, parts);
    populate_for_writing(v.data() + r.begin, r.end - r.begin);
  });
  v.resize(n);
}
template <typename Vector>
void resize_in_parts(Vector& v, std::size_t n, unsigned parts) {
  resize_in_parts(v, n, parts, n);
}

}  // namespace px
