// STEP and IGES parts (OpenCASCADE's readers, then the tessellation) on hostile bytes: the first
// byte picks the format. A refusal is an InputError; anything else is a finding.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "cad/tessellate.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string_view bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  try {
    mm::tessellate_cad(bytes, data[0] % 2 == 0 ? "step" : "iges", "fuzz");
  } catch (const mm::InputError&) {
  }
  return 0;
}
