#include "service/memory.h"

#include <malloc.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>

namespace mm::service {
namespace {

constexpr std::size_t kMiB = 1024 * 1024;
// The heap grows by this much beyond a request (virtual address space: a page costs only once
// touched), so that the region advised below is where the heap's blocks go.
constexpr std::size_t kHeapStep = 64 * kMiB;
constexpr std::uintptr_t kHugePage = 2 * kMiB;

// Transparent huge pages for the heap: the kernel then fills a touched heap region 2 MiB at a
// time instead of a fault per 4 KiB page (a decompression of rocker to level 3 touches 8 MB:
// 2,023 faults, 36 ms on a VM where a fault costs 12-15 us; with huge pages 7 faults, 8 ms),
// and the closest-point trees' scattered reads miss the TLB less. Advice only: where THP is
// off or unavailable nothing changes. RSS then grows in 2 MiB steps.
void advise_huge_pages_for_heap() {
  mallopt(M_TOP_PAD, static_cast<int>(kHeapStep));
  char* const before = static_cast<char*>(sbrk(0));
  // Grows the heap now (by the request and the step), so the region exists to be advised.
  void* volatile grow = std::malloc(kMiB);
  std::free(grow);
  char* const after = static_cast<char*>(sbrk(0));
  const std::uintptr_t lo = (reinterpret_cast<std::uintptr_t>(before) + kHugePage - 1) & ~(kHugePage - 1);
  const std::uintptr_t hi = reinterpret_cast<std::uintptr_t>(after) & ~(kHugePage - 1);
  if (before != reinterpret_cast<char*>(-1) && hi > lo) madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);
}

}  // namespace

void reuse_freed_memory() {
  // glibc's largest mmap threshold (DEFAULT_MMAP_THRESHOLD_MAX on 64-bit): above it a block is
  // mapped whatever is set, so a huge part's buffers still go back to the system when freed.
  mallopt(M_MMAP_THRESHOLD, 32 * kMiB);
  mallopt(M_TRIM_THRESHOLD, 512 * kMiB);
  advise_huge_pages_for_heap();
}

void return_freed_memory() { malloc_trim(0); }

}  // namespace mm::service
