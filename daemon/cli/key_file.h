// Customer key files of the offline CLI: 64 hexadecimal digits and a newline, mode 0600.
// The key itself never leaves these functions' callers' memory: outputs carry only its
// fingerprint, which identifies the key without revealing anything usable about it.
#pragma once
#include <string>

#include "watermark/key_stream.h"

namespace mm::cli {

// Throws InputError(path, reason): missing, unreadable, not exactly 64 hex digits (surrounding
// whitespace allowed).
Key read_key_file(const std::string& path);

// True when group or others may read or write the file (keys belong in mode 0600 files).
bool key_file_exposed(const std::string& path);

// "mmkey1:" + hex BLAKE2b-256 keyed by the key over a fixed label: a one-way key id (a MAC of a
// constant), so a record can name the key it was made with and a wrong key file is noticed.
std::string key_fingerprint(const Key& key);

// The file's text form: hex + "\n".
std::string key_file_text(const Key& key);

}  // namespace mm::cli
