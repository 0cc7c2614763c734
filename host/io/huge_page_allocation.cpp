// Large allocations on transparent huge pages: the replaceable global operator new and delete.
//
// A paper-size scene fills a few GB of fresh memory at start (10M triangles: the scene's
// triangles, Embree's build primitives, the flattened tree, the device layout). On 4 KiB pages
// every first touch is a page fault, and a cold start spent more time in the kernel clearing
// fresh pages than in parallax; on 2 MiB pages it takes a fraction of the faults, and loading
// the scene and building the BVH both got faster (docs/measurements.md, Start at paper scale).
//
// Linux gives anonymous memory huge pages where the process asks (the common setting of
// /sys/kernel/mm/transparent_hugepage/enabled is "madvise"), so every allocation of at least
// kHugeFrom bytes is marked MADV_HUGEPAGE before anything touches it. Smaller ones are left
// alone: a huge page is only worth it for memory that is filled whole. The memory still comes
// from malloc and goes back through free, so nothing else changes (glibc serves blocks this
// large with mmap, which is what can then be backed by huge pages). PARALLAX_HUGE_PAGES=off
// turns the advice off. Under AddressSanitizer the sanitizer's own operator new stays.
#include "io/environment.h"

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <new>

#include <sys/mman.h>

#if defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || __has_feature(memory_sanitizer)
#define PX_SANITIZER_ALLOCATOR 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define PX_SANITIZER_ALLOCATOR 1
#endif

namespace px {

// Linked in whether or not this file replaces operator new, so that a test can ask.
bool huge_page_allocation_compiled_in() {
#ifdef PX_SANITIZER_ALLOCATOR
  return false;
#else
  return true;
#endif
}

}  // namespace px

#ifndef PX_SANITIZER_ALLOCATOR

namespace {

constexpr std::size_t kHugePage = std::size_t{2} << 20;
constexpr std::size_t kHugeFrom = std::size_t{8} << 20;  // 4 huge pages at least

bool huge_pages_wanted() { return px::environment().huge_pages; }

// The whole 2 MiB pages inside [p, p + n). A failure (a kernel without THP) only loses speed.
void advise_huge_pages(void* p, std::size_t n) {
  const auto begin = (reinterpret_cast<std::uintptr_t>(p) + kHugePage - 1) & ~(kHugePage - 1);
  const auto end = (reinterpret_cast<std::uintptr_t>(p) + n) & ~(kHugePage - 1);
  if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
}

// Large blocks start on a cache line. glibc serves them with mmap, whose chunk header puts the
// block 16 bytes past a page boundary, so every 64 bytes of an array in it straddled two
// lines: a 256-byte 8-wide BVH node then spans 5 lines, half its 32-byte plane rows are split
// loads, and a 160-byte leaf block spans 4 lines every other block (CPU devices read the node
// buffer in place: CL_MEM_USE_HOST_PTR; docs/measurements.md, "Where the trace kernel loses to
// Embree"). posix_memalign'd memory goes back through free.
constexpr std::size_t kLineAlignFrom = std::size_t{64} << 10;
constexpr std::size_t kCacheLine = 64;

void* allocate_block(std::size_t n) {
  if (n < kLineAlignFrom) return std::malloc(n == 0 ? 1 : n);
  void* p = nullptr;
  return posix_memalign(&p, kCacheLine, n) == 0 ? p : nullptr;
}

void* allocate(std::size_t n) {
  for (;;) {
    void* p = allocate_block(n);
    if (p) {
      if (n >= kHugeFrom && huge_pages_wanted()) advise_huge_pages(p, n);
      return p;
    }
    // As the standard's operator new: the new-handler may free memory and let us try again.
    const std::new_handler handler = std::get_new_handler();
    if (!handler) throw std::bad_alloc();
    handler();
  }
}

void* allocate_nothrow(std::size_t n) noexcept {
  try {
    return allocate(n);
  } catch (...) {
    return nullptr;
  }
}

}  // namespace

void* operator new(std::size_t n) { return allocate(n); }
void* operator new[](std::size_t n) { return allocate(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return allocate_nothrow(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return allocate_nothrow(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }

#endif  // PX_SANITIZER_ALLOCATOR
