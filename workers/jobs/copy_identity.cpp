#include "jobs/copy_identity.h"

#include <sodium.h>

#include <algorithm>

#include "jobs/payload.h"

namespace mm::jobs {

CopyIdentity derive_copy_identity(const std::vector<std::string>& fields, const Key* key) {
  std::string msg = "meshmark-copy-v1";
  for (const auto& f : fields) msg += "|" + f;
  unsigned char h[32];
  crypto_generichash(h, sizeof h, reinterpret_cast<const unsigned char*>(msg.data()), msg.size(),
                     key ? key->data() : nullptr, key ? key->size() : 0);
  CopyIdentity id;
  std::copy(h, h + 24, id.nonce.begin());
  for (int i = 0; i < 8; ++i) id.payload |= std::uint64_t(h[24 + i]) << (8 * i);
  return id;
}

CopyIdentity issue_copy_identity(const std::string& asset_sha256, std::int64_t customer_id, int key_version,
                                 const std::string& idempotency_key, int bits, const std::set<std::string>& taken) {
  for (int counter = 0;; ++counter) {
    CopyIdentity id = derive_copy_identity({asset_sha256, std::to_string(customer_id), std::to_string(key_version),
                                            idempotency_key, std::to_string(counter)});
    if (bits < 64) id.payload &= (std::uint64_t(1) << bits) - 1;
    if (!taken.count(payload_hex(id.payload, bits))) return id;
  }
}

}  // namespace mm::jobs
