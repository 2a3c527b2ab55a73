// Copy records (`meshmark embed`'s .mmrec.json, read back by `meshmark extract`) on hostile
// text: refused with InputError or read, nothing else.
#include <cstddef>
#include <cstdint>
#include <string>

#include "cli/copy_record.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    mm::cli::record_from_json(text, "fuzz.mmrec.json");
  } catch (const mm::InputError&) {
  }
  return 0;
}
