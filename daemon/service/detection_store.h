// The store as a detect job sees it (jobs::DetectionStore) over the daemon's SQLite store.
#pragma once
#include "jobs/detect_suspect.h"
#include "store/store.h"

namespace mm::service {

// The list_copies limit that means every copy (protect's payload uniqueness, detection).
constexpr int kAllCopies = 1000000;

class StoreForDetection final : public jobs::DetectionStore {
 public:
  explicit StoreForDetection(store::Store& st) : st_(st) {}
  std::vector<jobs::IssuedCopyRecord> issued_copies() override;
  std::optional<std::int64_t> asset_with_sha256(const std::string& sha256) override;
  std::optional<jobs::PolyhedronRecord> polyhedron(std::int64_t asset_id, const std::string& prepare_key) override;
  std::vector<std::uint8_t> blob(const std::string& sha256) override;
  Key customer_key(std::int64_t customer_id, int key_version) override;

 private:
  store::Store& st_;
};

}  // namespace mm::service
