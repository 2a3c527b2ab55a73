// API tokens: only each token's SHA-256 is stored (a token is 32 random bytes, so a plain hash
// cannot be reversed by search); the token text leaves the store once, from create_token.
#include <sodium.h>

#include "store/sqlite_store_impl.h"
#include "support/sha256.h"

namespace mm::store::sqlite_detail {
namespace {

ApiToken read_token(const Stmt& s) {
  ApiToken t;
  t.id = s.i64(0);
  t.name = s.text(1);
  t.role = token_role_from_string(s.text(2));
  t.created_at = s.i64(3);
  t.revoked_at = s.opt_i64(4);
  return t;
}

std::string sha256_hex(const std::string& text) { return support::sha256_hex(text.data(), text.size()); }

}  // namespace

NewToken SqliteStore::create_token(const std::string& name, TokenRole role, const std::string& actor) {
  if (!valid_customer_name(name))
    throw StoreError("invalid token name '" + clip(name, 64) +
                     "': use 1-64 letters, digits, '.', '_' or '-', not starting with '.'");
  unsigned char raw[32];
  randombytes_buf(raw, sizeof raw);
  char hex[2 * sizeof raw + 1];
  sodium_bin2hex(hex, sizeof hex, raw, sizeof raw);
  sodium_memzero(raw, sizeof raw);
  NewToken out;
  out.secret = std::string("mmt_") + hex;
  sodium_memzero(hex, sizeof hex);
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  {
    Stmt q(db_, "SELECT 1 FROM api_tokens WHERE name = ?");
    if (q.bind(1, name).step()) throw StoreError("token '" + name + "' already exists");
  }
  const Millis t = now();
  Stmt ins(db_, "INSERT INTO api_tokens(name, role, token_sha256, created_at) VALUES(?, ?, ?, ?) RETURNING id");
  ins.bind(1, name).bind(2, to_string(role)).bind(3, sha256_hex(out.secret)).bind(4, t).step();
  out.token = {ins.i64(0), name, role, t, std::nullopt};
  insert_audit({actor, "token.create", "token:" + std::to_string(out.token.id),
                json{{"name", name}, {"role", to_string(role)}}.dump()});
  tx.commit();
  return out;
}

std::vector<ApiToken> SqliteStore::list_tokens() {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, sel(kTokenCols, "FROM api_tokens ORDER BY id").c_str());
  std::vector<ApiToken> out;
  while (q.step()) out.push_back(read_token(q));
  return out;
}

bool SqliteStore::revoke_token(const std::string& name, const std::string& actor) {
  std::lock_guard<std::mutex> l(m_);
  Tx tx(db_);
  Stmt q(db_, "UPDATE api_tokens SET revoked_at = ? WHERE name = ? AND revoked_at IS NULL RETURNING id");
  if (!q.bind(1, now()).bind(2, name).step()) return false;
  insert_audit({actor, "token.revoke", "token:" + std::to_string(q.i64(0)), json{{"name", name}}.dump()});
  tx.commit();
  return true;
}

std::optional<ApiToken> SqliteStore::token_for_secret(const std::string& secret) {
  std::lock_guard<std::mutex> l(m_);
  Stmt q(db_, sel(kTokenCols, "FROM api_tokens WHERE token_sha256 = ? AND revoked_at IS NULL").c_str());
  if (!q.bind(1, sha256_hex(secret)).step()) return std::nullopt;
  return read_token(q);
}

}  // namespace mm::store::sqlite_detail
