// A copy's identity: the nonce that seeds its key stream and the payload that names it among the
// copies of its asset. Derived, never drawn at random, so a re-run after a crash (or the same
// command twice) reproduces the same copy byte for byte.
#pragma once
#include <cstdint>
#include <set>
#include <string>
#include <vector>

#include "watermark/key_stream.h"

namespace mm::jobs {

struct CopyIdentity {
  Nonce nonce{};
  std::uint64_t payload = 0;  // all 64 bits; the caller keeps the payload width it embeds
};

// BLAKE2b-256 of "meshmark-copy-v1|" followed by `fields` joined with '|', keyed by `key` when
// given: the first 24 bytes are the nonce, the last 8 the payload (little-endian). The one place
// a copy's nonce is derived. Unkeyed, the identity is public (the key protects the mark); keyed,
// it tells nothing without the key.
CopyIdentity derive_copy_identity(const std::vector<std::string>& fields, const Key* key = nullptr);

// The daemon's copy of an asset for a customer: the identity of (asset, customer, key version,
// idempotency key, counter) for the first counter whose `bits`-bit payload is not in `taken`
// (the payloads of the asset's other copies, as payload_hex()).
CopyIdentity issue_copy_identity(const std::string& asset_sha256, std::int64_t customer_id, int key_version,
                                 const std::string& idempotency_key, int bits, const std::set<std::string>& taken);

}  // namespace mm::jobs
