#include "support/fault_injection.h"

#include <cstdlib>
#include <map>
#include <mutex>
#include <string>

namespace mm::support {

bool injected_fault(const char* env_var) {
  const char* v = std::getenv(env_var);
  if (!v) return false;
  const long fail_at = std::strtol(v, nullptr, 10);
  static std::mutex m;
  static std::map<std::string, long> calls;
  std::lock_guard<std::mutex> l(m);
  return fail_at > 0 && ++calls[env_var] == fail_at;
}

}  // namespace mm::support
