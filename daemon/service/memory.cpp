#include "service/memory.h"

#include <malloc.h>

namespace mm::service {

void reuse_freed_memory() {
  // glibc's largest mmap threshold (DEFAULT_MMAP_THRESHOLD_MAX on 64-bit): above it a block is
  // mapped whatever is set, so a huge part's buffers still go back to the system when freed.
  mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);
  mallopt(M_TRIM_THRESHOLD, 512 * 1024 * 1024);
}

void return_freed_memory() { malloc_trim(0); }

}  // namespace mm::service
