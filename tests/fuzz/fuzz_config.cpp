// The daemon's config loader on hostile text: refused with ConfigError or loaded, nothing else.
#include <cstddef>
#include <cstdint>
#include <string>

#include "service/config.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    mm::service::parse_config(text, "fuzz.json", "/nonexistent", false);
  } catch (const mm::service::ConfigError&) {
  }
  return 0;
}
