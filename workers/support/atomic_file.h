// Files that readers see whole or not at all: every writer of the project (meshes, streams,
// images, copy records, keys, reason files) goes through these two functions.
//
// The bytes go to a temporary file beside the target, ".<name>.tmp.XXXXXX", which is written,
// given its mode, fsynced and renamed over the target (or hard-linked, for an exclusive write);
// then the folder is fsynced so the rename survives a power loss. On any failure the temporary
// is removed and std::system_error is thrown with the errno of the step that failed (ENOSPC and
// EIO stay visible to callers that retry) and a message naming the step, not the path.
#pragma once
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace mm::support {

void write_file_atomic(const std::string& path, std::string_view bytes, unsigned mode = 0644);
void write_file_atomic(const std::string& path, const std::vector<std::uint8_t>& bytes, unsigned mode = 0644);

// Never replaces an existing file: false (and nothing left behind) when `path` exists, even if
// it appeared a moment earlier.
bool write_file_exclusive(const std::string& path, std::string_view bytes, unsigned mode = 0600);

// Whether `filename` (no folder) is such a temporary, as a crash mid-write leaves it.
bool is_atomic_write_temporary(const std::string& filename);

}  // namespace mm::support
