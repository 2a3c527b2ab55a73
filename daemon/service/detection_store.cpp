#include "service/detection_store.h"


namespace mm::service {

std::vector<jobs::IssuedCopyRecord> StoreForDetection::issued_copies() {
  std::vector<jobs::IssuedCopyRecord> out;
  for (auto& c : st_.list_copies(std::nullopt, kAllCopies)) {
    jobs::IssuedCopyRecord r;
    r.id = c.id;
    r.asset_id = c.asset_id;
    r.customer_id = c.customer_id;
    r.key_version = c.key_version;
    r.nonce = std::move(c.nonce);
    r.payload_hex = std::move(c.payload_hex);
    r.params_json = std::move(c.params_json);
    r.outputs_json = std::move(c.outputs_json);
    out.push_back(std::move(r));
  }
  return out;
}

std::optional<std::int64_t> StoreForDetection::asset_with_sha256(const std::string& sha256) {
  if (!store::is_sha256_hex(sha256)) return std::nullopt;
  if (auto a = st_.find_asset(sha256)) return a->id;
  return std::nullopt;
}

std::optional<jobs::PolyhedronRecord> StoreForDetection::polyhedron(std::int64_t asset_id,
                                                                     const std::string& prepare_key) {
  auto row = st_.find_polyhedron(asset_id, prepare_key);
  if (!row) return std::nullopt;
  return jobs::PolyhedronRecord{row->id, row->polyhedron_blob, row->basis_blob, row->meta_json};
}

std::vector<std::uint8_t> StoreForDetection::blob(const std::string& sha256) { return st_.blobs().get(sha256); }

Key StoreForDetection::customer_key(std::int64_t customer_id, int key_version) {
  return st_.customer_key(customer_id, key_version).key.bytes();
}

}  // namespace mm::service
