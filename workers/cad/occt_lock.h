// OpenCASCADE's data-exchange readers and writers keep process-wide state (the STEP parser's
// tables, the static parameters): one of them runs at a time in a process.
#pragma once
#include <mutex>

namespace mm::cad {
std::mutex& occt_mutex();
// OpenCASCADE reports to stdout by default; meshmark's errors name the file instead. Idempotent.
void silence_occt();
}  // namespace mm::cad
