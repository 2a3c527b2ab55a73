#include "service/build_info.h"

#include "support/sha256.h"

#ifndef MESHMARK_VERSION
#define MESHMARK_VERSION "unknown"
#endif

namespace mm::service {

std::string meshmark_version() { return MESHMARK_VERSION; }

std::string build_sha256() {
  static const std::string id = [] {
    try {
      return support::sha256_file_hex("/proc/self/exe");
    } catch (const std::exception&) {
      return std::string("unknown");
    }
  }();
  return id;
}

}  // namespace mm::service
