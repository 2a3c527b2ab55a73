// The heap policy both executables set at start-up (service/memory.h): blocks up to 32 MiB come
// from the heap and stay there when freed, and the heap is advised to use huge pages. Read back
// from the kernel's own account of this process's mappings (/proc/self/smaps).
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>

#include "service/memory.h"

namespace {

// The smaps entry of the mapping holding `p`: its header line and its VmFlags.
struct Mapping {
  std::string header, flags;
};

Mapping mapping_of(const void* p) {
  const auto at = reinterpret_cast<std::uintptr_t>(p);
  std::ifstream smaps("/proc/self/smaps");
  std::string line;
  Mapping found;
  bool inside = false;
  while (std::getline(smaps, line)) {
    std::uintptr_t lo = 0, hi = 0;
    char dash = 0;
    std::istringstream head(line);
    if (head >> std::hex >> lo >> dash >> hi && dash == '-' && line.find(':') > line.find(' ')) {
      inside = lo <= at && at < hi;
      if (inside) found.header = line;
    } else if (inside && line.rfind("VmFlags:", 0) == 0) {
      found.flags = line;
    }
  }
  return found;
}

TEST(HeapPolicy, LargeBlocksComeFromTheHeapAdvisedForHugePages) {
  mm::service::reuse_freed_memory();
  // 8 MiB: above glibc's default mmap threshold (128 KiB), below the policy's 32 MiB.
  void* block = std::malloc(8 * 1024 * 1024);
  ASSERT_NE(block, nullptr);
  std::memset(block, 1, 8 * 1024 * 1024);
  // Its middle: the advice starts at the first 2 MiB boundary of the heap's new region.
  const Mapping m = mapping_of(static_cast<char*>(block) + 4 * 1024 * 1024);
  std::free(block);
  ASSERT_FALSE(m.header.empty()) << "no mapping holds the block";
  EXPECT_NE(m.header.find("[heap]"), std::string::npos) << m.header;
  // The advice needs a kernel built with transparent huge pages (whatever their setting).
  if (std::ifstream("/sys/kernel/mm/transparent_hugepage/enabled")) {
    EXPECT_NE(m.flags.find(" hg"), std::string::npos) << m.header << "\n" << m.flags;
  }
  mm::service::return_freed_memory();
}

}  // namespace
