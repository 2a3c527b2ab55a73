// Fault injection for the hardening tests, as SQLite tests itself: with the environment variable
// set to N, the Nth call for that variable in this process returns true and the caller fails as
// it would on a real fault. Unset in production (scripts/torture.sh sets them).
#pragma once

namespace mm::support {

// MESHMARK_FAIL_WRITE: atomic file writes (ENOSPC); MESHMARK_FAIL_DB_WRITE: store commits.
bool injected_fault(const char* env_var);

}  // namespace mm::support
