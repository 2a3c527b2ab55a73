// OpenCASCADE's data-exchange writers keep process-wide state (the static parameters): the
// sample writer runs one at a time in a process. Readers run in child processes (tessellate.h).
#pragma once
#include <mutex>

namespace mm::cad {
std::mutex& occt_mutex();
// OpenCASCADE reports to stdout by default; meshmark's errors name the file instead. Idempotent.
void silence_occt();
}  // namespace mm::cad
