// Shared by keys.cpp and signing.cpp: libsodium's one-time start and the trimming of key text.
#pragma once
#include <sodium.h>

#include <string>

#include "keys/keys.h"

namespace mm::keys::detail {

inline void ensure_sodium() {
  static const int rc = sodium_init();  // thread-safe, idempotent
  if (rc < 0) throw KeyError("libsodium failed to initialize");
}

inline std::string trim(const std::string& s) {
  const char* ws = " \t\r\n";
  auto b = s.find_first_not_of(ws);
  if (b == std::string::npos) return {};
  return s.substr(b, s.find_last_not_of(ws) - b + 1);
}

}  // namespace mm::keys::detail
