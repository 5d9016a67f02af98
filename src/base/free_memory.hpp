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

}  // namespace pt
