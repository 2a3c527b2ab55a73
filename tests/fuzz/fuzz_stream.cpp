// The .mmc stream decoder on hostile bytes: refused with InputError or decoded, nothing else.
#include <cstddef>
#include <cstdint>

#include "codec/stream.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    mm::decode(data, size, "fuzz");
  } catch (const mm::InputError&) {
  }
  return 0;
}
