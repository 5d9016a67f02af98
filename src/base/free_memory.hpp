// Returning freed memory to the system between the phases of a large build.
#pragma once

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace pt {

// glibc keeps freed blocks below its (self-raising, up to 32 MB) mmap threshold in its heaps, still resident, and
// TBB's worker threads allocate from heaps of their own: without this, a large mesh's freed transient arrays
// (boxes, the builder's second halves, the triangles before reordering) stay in the process's resident memory
// while the next phase allocates fresh pages. A no-op elsewhere.
inline void release_free_memory() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

// glibc puts blocks below a threshold into heaps; by default the threshold rises (up to 32 MB) each time a larger
// block is freed, and the heaps of other threads are not trimmed from their top by malloc_trim. A large scene's
// build (the BVH builder's parallel halves on TBB's threads) then leaves tens of megabytes free but resident through
// its peak. A fixed threshold of 4 MB gives every large array its own mapping, back to the system when freed.
// Called once, at the start of the program. A no-op elsewhere.
inline void return_large_blocks_when_freed() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 4 << 20);
#endif
}

}  // namespace pt
