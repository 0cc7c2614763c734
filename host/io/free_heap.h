// give_back_free_heap(): the allocator's free memory handed back to the system between the steps
// of a large start.
//
// glibc keeps what is freed below its mmap threshold in its heap (the threshold grows as large
// blocks are freed, up to 32 MiB a block, so a large scene's loader and validator arrays land
// there), and returns heap memory to the system only from the heap's top, and only past a trim
// threshold that grows likewise. So a step's freed arrays stayed resident and stood beside the
// next step's at its highest point: the glTF loader's decoded attributes beside the shading
// records being made, the validator's tables beside the device layout, the layout's temporaries
// beside the first frame (docs/measurements.md, "What is resident at each
// highest point"). malloc_trim hands back every whole free page of every arena.
#pragma once

#include <cstddef>

#include <malloc.h>

namespace px {

// Starts of at least this many triangles trim between their steps; a smaller start's free heap
// is not worth the page faults of touching it again.
constexpr std::size_t kGiveBackHeapFrom = 1000000;

inline void give_back_free_heap(std::size_t triangles) {
  if (triangles >= kGiveBackHeapFrom) malloc_trim(0);
}

}  // namespace px
