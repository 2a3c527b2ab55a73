// Small file helpers for the command-line tools: whole-file reads, atomic writes, hashes.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace mm::cli {

std::vector<std::uint8_t> read_file_bytes(const std::string& path);  // throws InputError

// Writes to a temporary name in the same folder, fsyncs, renames: readers never see a half file.
// `mode` is applied before the data is written (0600 for secrets).
void write_file_atomic(const std::string& path, const std::string& data, unsigned mode = 0644);

// The same, but never replaces an existing file: the temporary is hard-linked to `path`, which
// fails if anything is there, even a file created a moment earlier. Returns false (and leaves
// nothing behind) when `path` exists; throws InputError for other failures.
bool write_file_exclusive(const std::string& path, const std::string& data, unsigned mode = 0600);

std::string sha256_hex(const std::uint8_t* data, std::size_t size);
std::string sha256_file_hex(const std::string& path);

std::string to_hex(const std::uint8_t* data, std::size_t size);
std::vector<std::uint8_t> from_hex(const std::string& hex);  // throws std::invalid_argument

}  // namespace mm::cli
