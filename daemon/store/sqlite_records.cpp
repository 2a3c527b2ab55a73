// The store's records: customers and keys, assets and polyhedra, copies and detections, audit.
#include "store/sqlite_store_impl.h"

namespace mm::store::sqlite_detail {

Customer SqliteStore::add_customer(const std::string& name, const std::string& actor) {
  if (!valid_customer_name(name))
    throw StoreError("invalid customer name '" + clip(name, 64) +
                     "': use 1-64 letters, digits, '.', '_' or '-', not starting with '.'");
  const keys::SecretKey& master = need_master();
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  Millis t = now();
  {
    Stmt q(db_, "SELECT 1 FROM customers WHERE name = ?");
    if (q.bind(1, name).step()) throw StoreError("customer '" + name + "' already exists");
  }
  Stmt ins(db_, "INSERT INTO customers(name, current_key_version, created_at) VALUES(?, 1, ?) RETURNING id");
  ins.bind(1, name).bind(2, t).step();
  std::int64_t id = ins.i64(0);
  insert_key(master, id, 1, t);
  insert_audit({actor, "customer.add", "customer:" + std::to_string(id),
                json{{"name", name}, {"key_version", 1}}.dump()});
  tx.commit();
  return {id, name, 1, t};
}

std::vector<Customer> SqliteStore::list_customers() {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, sel(kCustomerCols, "FROM customers ORDER BY id").c_str());
  std::vector<Customer> out;
  while (q.step()) out.push_back(read_customer(q));
  return out;
}

std::optional<Customer> SqliteStore::find_customer(const std::string& name) {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, sel(kCustomerCols, "FROM customers WHERE name = ?").c_str());
  if (!q.bind(1, name).step()) return std::nullopt;
  return read_customer(q);
}

std::optional<Customer> SqliteStore::get_customer(std::int64_t id) {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, sel(kCustomerCols, "FROM customers WHERE id = ?").c_str());
  if (!q.bind(1, id).step()) return std::nullopt;
  return read_customer(q);
}

int SqliteStore::rotate_key(std::int64_t customer_id, const std::string& actor) {
  const keys::SecretKey& master = need_master();
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  Stmt q(db_, "SELECT current_key_version FROM customers WHERE id = ?");
  if (!q.bind(1, customer_id).step()) throw StoreError("no customer with id " + std::to_string(customer_id));
  int v = static_cast<int>(q.i64(0)) + 1;
  Millis t = now();
  insert_key(master, customer_id, v, t);
  Stmt u(db_, "UPDATE customers SET current_key_version = ? WHERE id = ?");
  u.bind(1, v).bind(2, customer_id).run();
  insert_audit({actor, "key.rotate", "customer:" + std::to_string(customer_id),
                json{{"key_version", v}}.dump()});
  tx.commit();
  return v;
}

CustomerKey SqliteStore::customer_key(std::int64_t customer_id, int version) {
  const keys::SecretKey& master = need_master();
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_,
         "SELECT k.version, k.nonce, k.ciphertext FROM customer_keys k JOIN customers c "
         "ON c.id = k.customer_id WHERE k.customer_id = ?1 "
         "AND k.version = CASE WHEN ?2 = 0 THEN c.current_key_version ELSE ?2 END");
  if (!q.bind(1, customer_id).bind(2, version).step())
    throw keys::KeyError("no key version " + (version == 0 ? std::string("(current)") : std::to_string(version)) +
                         " for customer " + std::to_string(customer_id));
  int v = static_cast<int>(q.i64(0));
  keys::SealedKey sealed{q.blob(1), q.blob(2)};
  return {customer_id, v, keys::open_customer_key(master, sealed, customer_id, v)};
}

std::vector<KeyInfo> SqliteStore::list_keys(std::int64_t customer_id) {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, "SELECT customer_id, version, created_at FROM customer_keys WHERE customer_id = ? ORDER BY version");
  q.bind(1, customer_id);
  std::vector<KeyInfo> out;
  while (q.step()) out.push_back({q.i64(0), static_cast<int>(q.i64(1)), q.i64(2)});
  return out;
}

Asset SqliteStore::put_asset_file(const std::string& path, const std::string& name) {
  std::string h = blobs_.put_file(path);  // durable before any row points at it
  return upsert_asset(h, blobs_.size(h), name);
}

Asset SqliteStore::put_asset_bytes(const std::vector<std::uint8_t>& bytes, const std::string& name) {
  std::string h = blobs_.put(bytes);
  return upsert_asset(h, bytes.size(), name);
}

std::optional<Asset> SqliteStore::get_asset(std::int64_t id) {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, sel(kAssetCols, "FROM assets WHERE id = ?").c_str());
  if (!q.bind(1, id).step()) return std::nullopt;
  return read_asset(q);
}

std::optional<Asset> SqliteStore::find_asset(const std::string& sha256) {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, sel(kAssetCols, "FROM assets WHERE sha256 = ?").c_str());
  if (!q.bind(1, sha256).step()) return std::nullopt;
  return read_asset(q);
}

std::vector<Asset> SqliteStore::list_assets(int limit) {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, sel(kAssetCols, "FROM assets ORDER BY id DESC LIMIT ?").c_str());
  q.bind(1, limit);
  std::vector<Asset> out;
  while (q.step()) out.push_back(read_asset(q));
  return out;
}

Polyhedron SqliteStore::put_polyhedron(const Polyhedron& p) {
  if (!blobs_.contains(p.polyhedron_blob))
    throw StoreError("polyhedron blob " + clip(p.polyhedron_blob, 64) + " is not in the blob store");
  if (!p.basis_blob.empty() && !blobs_.contains(p.basis_blob))
    throw StoreError("basis blob " + clip(p.basis_blob, 64) + " is not in the blob store");
  require_json(p.meta_json, "polyhedron meta_json");
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  Stmt ins(db_,
           "INSERT INTO polyhedra(asset_id, params_key, polyhedron_blob, basis_blob, meta_json, created_at) "
           "VALUES(?,?,?,?,?,?) ON CONFLICT(asset_id, params_key) DO NOTHING");
  ins.bind(1, p.asset_id).bind(2, p.params_key).bind(3, p.polyhedron_blob).bind(4, p.basis_blob)
      .bind(5, p.meta_json).bind(6, now()).run();
  Stmt q(db_, sel(kPolyCols, "FROM polyhedra WHERE asset_id = ? AND params_key = ?").c_str());
  q.bind(1, p.asset_id).bind(2, p.params_key).step();
  Polyhedron out = read_poly(q);
  tx.commit();
  return out;
}

std::optional<Polyhedron> SqliteStore::find_polyhedron(std::int64_t asset_id, const std::string& params_key) {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, sel(kPolyCols, "FROM polyhedra WHERE asset_id = ? AND params_key = ?").c_str());
  if (!q.bind(1, asset_id).bind(2, params_key).step()) return std::nullopt;
  return read_poly(q);
}

IssuedCopy SqliteStore::issue_copy(const NewCopy& c) {
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  bool existed = false;
  std::int64_t id = insert_copy(c, std::nullopt, "cli", existed);
  tx.commit();
  return *copy_by_id(id);
}

std::optional<IssuedCopy> SqliteStore::find_copy(std::int64_t asset_id, std::int64_t customer_id, int key_version, const std::string& idempotency_key) {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, sel(kCopyCols, "FROM issued_copies WHERE asset_id = ? AND customer_id = ? AND "
                             "key_version = ? AND idempotency_key = ?").c_str());
  if (!q.bind(1, asset_id).bind(2, customer_id).bind(3, key_version).bind(4, idempotency_key).step())
    return std::nullopt;
  return read_copy(q);
}

std::optional<IssuedCopy> SqliteStore::get_copy(std::int64_t id) {
  std::lock_guard<std::mutex> l(m_);
  return copy_by_id(id);
}

std::vector<IssuedCopy> SqliteStore::list_copies(std::optional<std::int64_t> asset_id, int limit) {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, sel(kCopyCols, "FROM issued_copies WHERE (?1 IS NULL OR asset_id = ?1) "
                             "ORDER BY id DESC LIMIT ?2").c_str());
  q.bind(1, asset_id).bind(2, limit);
  std::vector<IssuedCopy> out;
  while (q.step()) out.push_back(read_copy(q));
  return out;
}

Detection SqliteStore::record_detection(const NewDetection& d) {
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  std::int64_t id = insert_detection(d, std::nullopt, "cli");
  tx.commit();
  Stmt q(db_, sel(kDetectionCols, "FROM detections WHERE id = ?").c_str());
  q.bind(1, id).step();
  return read_detection(q);
}

std::vector<Detection> SqliteStore::list_detections(int limit) {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, sel(kDetectionCols, "FROM detections ORDER BY id DESC LIMIT ?").c_str());
  q.bind(1, limit);
  std::vector<Detection> out;
  while (q.step()) out.push_back(read_detection(q));
  return out;
}

std::optional<Detection> SqliteStore::get_detection(std::int64_t id) {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, sel(kDetectionCols, "FROM detections WHERE id = ?").c_str());
  q.bind(1, id);
  if (!q.step()) return std::nullopt;
  return read_detection(q);
}

std::optional<Detection> SqliteStore::detection_of_job(std::int64_t job_id) {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, sel(kDetectionCols, "FROM detections WHERE job_id = ? ORDER BY id DESC LIMIT 1").c_str());
  q.bind(1, job_id);
  if (!q.step()) return std::nullopt;
  return read_detection(q);
}

std::int64_t SqliteStore::append_audit(const NewAudit& a) {
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  std::int64_t id = insert_audit(a);
  tx.commit();
  return id;
}

std::vector<AuditEntry> SqliteStore::list_audit(int limit) {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, "SELECT id, at, actor, action, subject, details_json FROM audit_log ORDER BY id DESC LIMIT ?");
  q.bind(1, limit);
  std::vector<AuditEntry> out;
  while (q.step()) {
    AuditEntry e;
    e.id = q.i64(0);
    e.at = q.i64(1);
    e.actor = q.text(2);
    e.action = q.text(3);
    e.subject = q.text(4);
    e.details_json = q.text(5);
    out.push_back(std::move(e));
  }
  return out;
}

}  // namespace mm::store::sqlite_detail
