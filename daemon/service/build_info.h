// What a record says about the program that made it: the release version and the SHA-256 of the
// running executable (the build id: two builds of one version differ here).
#pragma once
#include <string>

namespace mm::service {

std::string meshmark_version();
std::string build_sha256();  // of /proc/self/exe, computed once; "unknown" if unreadable

}  // namespace mm::service

namespace mm::service {

// The method's measured false-attribution rate as the calibration benchmark last recorded it
// (docs/results/null.json, compiled in): trials, false attributions, the 95 % bound, the command
// and commit that measured it.
std::string false_attribution_record_json();

}  // namespace mm::service
