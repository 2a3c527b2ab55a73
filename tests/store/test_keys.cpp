#include <gtest/gtest.h>
#include <sodium.h>
#include <sys/stat.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "keys/keys.h"
#include "store/home.h"
#include "store/sqlite_db.h"
#include "store_backends.h"
#include "store_test_util.h"

using namespace mm;
using namespace mm::test;
using keys::SecretKey;

namespace {
std::string hex(const std::uint8_t* d, std::size_t n, bool upper = false) {
  std::string s(2 * n + 1, '\0');
  sodium_bin2hex(s.data(), s.size(), d, n);
  s.pop_back();
  if (upper)
    for (auto& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}
std::string b64(const std::uint8_t* d, std::size_t n, int variant) {
  std::string s(sodium_base64_encoded_len(n, variant), '\0');
  sodium_bin2base64(s.data(), s.size(), d, n, variant);
  s.resize(std::strlen(s.c_str()));
  return s;
}
std::string read_all(const std::string& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}
struct EnvGuard {
  ~EnvGuard() { ::unsetenv(keys::kMasterKeyEnv); }
};
}  // namespace

TEST(Keys, SealOpenRoundTripAndBinding) {
  SecretKey master = SecretKey::random();
  SecretKey k = SecretKey::random();
  auto sealed = keys::seal_customer_key(master, k, 3, 1);
  EXPECT_EQ(sealed.nonce.size(), 24u);
  EXPECT_EQ(sealed.ciphertext.size(), 48u);
  EXPECT_TRUE(keys::open_customer_key(master, sealed, 3, 1) == k);
  auto again = keys::seal_customer_key(master, k, 3, 1);
  EXPECT_NE(again.nonce, sealed.nonce) << "nonces must be random";
  // Wrong master key, another customer's row, another version, a flipped bit: all refused.
  EXPECT_THROW(keys::open_customer_key(SecretKey::random(), sealed, 3, 1), keys::KeyError);
  EXPECT_THROW(keys::open_customer_key(master, sealed, 4, 1), keys::KeyError);
  EXPECT_THROW(keys::open_customer_key(master, sealed, 3, 2), keys::KeyError);
  auto tampered = sealed;
  tampered.ciphertext[5] ^= 1;
  EXPECT_THROW(keys::open_customer_key(master, tampered, 3, 1), keys::KeyError);
  tampered = sealed;
  tampered.nonce.pop_back();
  EXPECT_THROW(keys::open_customer_key(master, tampered, 3, 1), keys::KeyError);
}

TEST(Keys, WrongMasterKeyErrorSaysSoWithoutKeyBytes) {
  SecretKey master = SecretKey::random();
  SecretKey wrong = SecretKey::random();
  SecretKey k = SecretKey::random();
  auto sealed = keys::seal_customer_key(master, k, 7, 2);
  try {
    keys::open_customer_key(wrong, sealed, 7, 2);
    FAIL();
  } catch (const keys::KeyError& e) {
    std::string m = e.what();
    EXPECT_NE(m.find("customer 7 version 2"), std::string::npos) << m;
    EXPECT_NE(m.find("wrong master key"), std::string::npos) << m;
    for (const SecretKey* s : {&master, &wrong, &k})
      EXPECT_EQ(m.find(hex(s->data(), 32)), std::string::npos);
  }
}

TEST(Keys, MasterKeyFileMustBeOwnerOnly) {
  TempDir dir;
  std::string p = dir / "master.key";
  keys::create_master_key_file(p);
  struct stat st {};
  ASSERT_EQ(::stat(p.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  SecretKey a = keys::load_master_key_file(p);
  EXPECT_TRUE(keys::load_master_key_file(p) == a);
  EXPECT_FALSE(a == SecretKey());
  EXPECT_THROW(keys::create_master_key_file(p), keys::KeyError) << "must never overwrite a key";
  EXPECT_TRUE(keys::load_master_key_file(p) == a);
  for (unsigned mode : {0640u, 0604u, 0644u, 0660u}) {
    ::chmod(p.c_str(), mode);
    try {
      keys::load_master_key_file(p);
      FAIL() << "accepted mode " << std::oct << mode;
    } catch (const keys::KeyError& e) {
      std::string m = e.what();
      EXPECT_NE(m.find(p), std::string::npos) << m;
      EXPECT_NE(m.find("chmod 600"), std::string::npos) << m;
    }
  }
  ::chmod(p.c_str(), 0400);
  EXPECT_TRUE(keys::load_master_key_file(p) == a);
  EXPECT_THROW(keys::load_master_key_file(dir / "absent.key"), keys::KeyError);
  std::string bad = dir / "bad.key";
  std::ofstream(bad) << "not a key at all";
  ::chmod(bad.c_str(), 0600);
  EXPECT_THROW(keys::load_master_key_file(bad), keys::KeyError);
}

TEST(Keys, MasterKeyFromEnvironmentHexOrBase64) {
  EnvGuard guard;
  SecretKey k = SecretKey::random();
  ::unsetenv(keys::kMasterKeyEnv);
  EXPECT_FALSE(keys::master_key_from_env());
  for (const std::string& text :
       {hex(k.data(), 32), hex(k.data(), 32, true), b64(k.data(), 32, sodium_base64_VARIANT_ORIGINAL),
        b64(k.data(), 32, sodium_base64_VARIANT_URLSAFE_NO_PADDING)}) {
    ::setenv(keys::kMasterKeyEnv, text.c_str(), 1);
    auto got = keys::master_key_from_env();
    ASSERT_TRUE(got) << text;
    EXPECT_TRUE(*got == k);
    EXPECT_TRUE(keys::load_master_key("/nonexistent/master.key") == k) << "environment wins";
  }
  ::setenv(keys::kMasterKeyEnv, "abcd", 1);
  try {
    keys::master_key_from_env();
    FAIL();
  } catch (const keys::KeyError& e) {
    EXPECT_EQ(std::string(e.what()).find("abcd"), std::string::npos) << "never echo the secret";
  }
}

// Customer keys in the store, on each backend.
class StoreKeys : public BackendTest {};
MM_BACKENDS(StoreKeys);

TEST_P(StoreKeys, StoreCustomerKeysRotateAndOldVersionsStay) {
  TempDir dir;
  auto o = options(dir);
  auto s = open_store(dir, o);
  auto acme = s->add_customer("acme");
  EXPECT_EQ(acme.current_key_version, 1);
  auto k1 = s->customer_key(acme.id);
  EXPECT_EQ(k1.version, 1);
  EXPECT_TRUE(s->customer_key(acme.id, 1).key == k1.key);
  EXPECT_EQ(s->rotate_key(acme.id), 2);
  auto k2 = s->customer_key(acme.id);
  EXPECT_EQ(k2.version, 2);
  EXPECT_FALSE(k2.key == k1.key);
  EXPECT_TRUE(s->customer_key(acme.id, 1).key == k1.key) << "old copies keep their key version";
  EXPECT_EQ(s->find_customer("acme")->current_key_version, 2);
  EXPECT_EQ(s->list_keys(acme.id).size(), 2u);
  auto other = s->add_customer("globex");
  EXPECT_FALSE(s->customer_key(other.id).key == k1.key);
  EXPECT_THROW(s->customer_key(acme.id, 3), keys::KeyError);
  EXPECT_THROW(s->add_customer("acme"), store::StoreError);
  for (const char* bad : {"", "../x", "a/b", "..", "has space", "x\n", "..x", ".hidden"})
    EXPECT_THROW(s->add_customer(bad), store::StoreError) << bad;

  // Wrong master key: refused when the store is opened; no master key at all: a clear KeyError.
  auto wrong = o;
  wrong.master_key = SecretKey::random();
  EXPECT_THROW(open_store(dir, wrong), keys::KeyError);
  auto none = o;
  none.master_key.reset();
  auto sn = open_store(dir, none);
  EXPECT_THROW(sn->customer_key(acme.id), keys::KeyError);
  EXPECT_EQ(sn->list_customers().size(), 2u) << "listing needs no key";
}

// A wrong master key is refused at open, before `customer add` or `rotate-key` can seal anything
// under it or the daemon starts: by the stored check value, or, for a store that has none yet, by
// the first sealed customer key.
TEST_P(StoreKeys, WrongMasterKeyIsRefusedWhenTheStoreOpens) {
  TempDir dir;
  auto o = options(dir);
  {
    auto s = open_store(dir, o);  // a new store records the key's check value
  }
  auto wrong = o;
  wrong.master_key = SecretKey::random();
  try {
    open_store(dir, wrong);
    FAIL() << "a new store accepted another master key";
  } catch (const keys::KeyError& e) {
    EXPECT_NE(std::string(e.what()).find("wrong master key"), std::string::npos) << e.what();
  }
  std::int64_t acme = 0;
  {
    auto s = open_store(dir, o);
    acme = s->add_customer("acme").id;
  }
  // A store from before the check value: the sealed key decides, and the check is recorded.
  stores().raw(dir, "DELETE FROM master_key_check");
  EXPECT_THROW(open_store(dir, wrong), keys::KeyError);
  {
    auto s = open_store(dir, o);
    EXPECT_EQ(s->customer_key(acme).version, 1);
  }
  EXPECT_THROW(open_store(dir, wrong), keys::KeyError);
  auto none = o;
  none.master_key.reset();
  EXPECT_NO_THROW(open_store(dir, none)) << "read-only use needs no key";
}

TEST(Keys, NoKeyMaterialAnywhereInTheDatabaseOrMessages) {
  TempDir dir;
  EnvGuard guard;
  ::unsetenv(keys::kMasterKeyEnv);
  auto home = store::resolve_home(dir / "home");
  ASSERT_TRUE(store::init_home(home));
  SecretKey master = keys::load_master_key_file(home.master_key);
  std::vector<SecretKey> secrets = {master};
  std::vector<std::string> messages;
  {
    store::StoreOptions base;
    base.backoff.base = 0;  // retry at once
    auto s = store::open_home(home, true, base);
    for (const char* name : {"acme", "globex", "initech"}) {
      auto c = s->add_customer(name);
      s->rotate_key(c.id);
      for (int v : {1, 2}) secrets.push_back(s->customer_key(c.id, v).key);
    }
    auto asset = s->put_asset_bytes({5, 6, 7}, "p.stl");
    auto acme = *s->find_customer("acme");
    auto j = s->enqueue({"protect", R"({"customer":"acme"})", 0, 2, "k1", {}}).job;
    ASSERT_TRUE(s->claim("w", 1000));
    try {
      s->fail(j.id, "w", "simulated failure");
    } catch (const std::exception& e) {
      messages.push_back(e.what());
    }
    ASSERT_TRUE(s->claim("w", 1000));
    store::JobRecords r;
    store::NewCopy c;
    c.asset_id = asset.id;
    c.customer_id = acme.id;
    c.key_version = 2;
    c.idempotency_key = "k1";
    c.nonce = std::vector<std::uint8_t>(24, 3);
    c.payload_hex = "abcd";
    r.copies = {c};
    s->complete(j.id, "w", r);
    // Provoke every key error we can and keep the messages.
    auto bad = [&](auto&& f) {
      try {
        f();
      } catch (const std::exception& e) {
        messages.push_back(e.what());
      }
    };
    bad([&] { s->customer_key(acme.id, 9); });
    store::StoreOptions wrong;
    wrong.db_path = home.db;
    wrong.master_key = SecretKey::random();
    bad([&] { store::open_sqlite_store(wrong); });  // refused: the key's check value differs
    EXPECT_GE(messages.size(), 2u);
  }
  // Everything on disk under home except the master key file itself, plus a full SQL dump.
  std::string everything;
  for (auto& e : std::filesystem::recursive_directory_iterator(home.root))
    if (e.is_regular_file() && e.path() != home.master_key) everything += read_all(e.path().string());
  for (const char* table : {"customers", "customer_keys", "assets", "jobs", "issued_copies",
                            "detections", "audit_log", "schema_version", "polyhedra", "master_key_check"})
  {
    std::string cols;
    for (auto& c : raw_query(home.db, std::string("SELECT name FROM pragma_table_info('") + table + "')"))
      cols += (cols.empty() ? "" : " || ',' || ") + std::string("quote(") + c + ")";
    for (auto& row : raw_query(home.db, "SELECT " + cols + " FROM " + table)) everything += row;
  }
  for (auto& row : raw_query(home.db, "SELECT hex(nonce) || hex(ciphertext) FROM customer_keys")) everything += row;
  for (auto& m : messages) everything += m;
  ASSERT_GT(everything.size(), 1000u);
  for (const SecretKey& k : secrets) {
    for (const std::string& form :
         {std::string(reinterpret_cast<const char*>(k.data()), 32), hex(k.data(), 32), hex(k.data(), 32, true),
          b64(k.data(), 32, sodium_base64_VARIANT_ORIGINAL),
          b64(k.data(), 32, sodium_base64_VARIANT_URLSAFE_NO_PADDING)}) {
      EXPECT_EQ(everything.find(form), std::string::npos) << "key material found on disk or in a message";
      // Also no long fragment (the first 12 bytes) of it.
      EXPECT_EQ(everything.find(form.substr(0, form.size() * 3 / 8)), std::string::npos);
    }
  }
}
