// Small file helpers for the command-line tools: whole-file reads, atomic writes, hashes.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "support/hex.h"
#include "support/sha256.h"

namespace mm::cli {

std::vector<std::uint8_t> read_file_bytes(const std::string& path);  // throws InputError

// support::write_file_atomic with InputError naming the path: readers never see a half file.
// `mode` is applied before the data is written (0600 for secrets).
void write_file_atomic(const std::string& path, const std::string& data, unsigned mode = 0644);

// The same, but never replaces an existing file: the temporary is hard-linked to `path`, which
// fails if anything is there, even a file created a moment earlier. Returns false (and leaves
// nothing behind) when `path` exists; throws InputError for other failures.
bool write_file_exclusive(const std::string& path, const std::string& data, unsigned mode = 0600);

// Hashes and hex: the project's one implementation (workers/support).
using support::from_hex;
using support::sha256_file_hex;
using support::sha256_hex;
using support::to_hex;

}  // namespace mm::cli
