// Outside programs the service runs (curl, chromium, timeout): argv as given, no shell.
#pragma once
#include <string>
#include <vector>

namespace mm::service {

// Runs argv (no shell: arguments are passed as they are), stdin from /dev/null, stdout and stderr
// to `log` (created 0600, or discarded). Returns the exit status, -1 when it could not start or
// was killed.
int run_program(const std::vector<std::string>& argv, const std::string& log = "/dev/null");

// Whether `program` is an executable on $PATH (or, with a '/', that file).
bool on_path(const std::string& program);

}  // namespace mm::service
