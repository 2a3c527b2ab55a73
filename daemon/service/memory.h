// The process's heap policy. glibc hands every allocation of 128 KiB or more (a dense
// measurement's 200,000 samples, a refined mesh) fresh pages from the kernel and gives them back
// on free, so a compress run that measures a dozen candidate surfaces takes each page fault
// again; on a virtual machine that was an eighth of the run (fandisk: 40,000 minor faults, 3.50
// -> 3.07 s wall). Freed memory is kept for reuse instead, and a long-running process hands it
// back between jobs. The heap asks for transparent huge pages, so what is touched first is
// faulted in 2 MiB at a time. Allocation policy only: no number a computation gives depends on it.
#pragma once

namespace mm::service {

// Call once at start-up, before threads: large blocks come from the heap (up to glibc's 32 MiB
// ceiling), freed memory stays with the process for its next allocations, and the heap's first
// 64 MiB are advised to use huge pages (madvise MADV_HUGEPAGE; the main thread's heap, not the
// arenas of other threads; heap the daemon's trim gives back and grows again is not advised).
void reuse_freed_memory();

// Gives the heap's free memory back to the system (malloc_trim); for a worker after each job,
// so an idle daemon does not sit on its largest job's memory.
void return_freed_memory();

}  // namespace mm::service
