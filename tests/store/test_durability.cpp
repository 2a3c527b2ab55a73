// The store's guards for SQLite's write-ahead log: no store on a network file system, and
// checkpoints that never race a commit (docs/store.md, "Durability").
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "store/sqlite_db.h"
#include "store_test_util.h"

using namespace mm;
using namespace mm::test;

TEST(Durability, NetworkFileSystemsAreNamedLocalOnesAreNot) {
  EXPECT_STREQ(store::sql::network_filesystem_name(0x6969), "NFS");
  EXPECT_STREQ(store::sql::network_filesystem_name(0xFF534D42L), "CIFS");
  EXPECT_STREQ(store::sql::network_filesystem_name(0xFE534D42L), "SMB2");
  EXPECT_STREQ(store::sql::network_filesystem_name(0x00C36400), "Ceph");
  EXPECT_EQ(store::sql::network_filesystem_name(0xEF53), nullptr);      // ext4
  EXPECT_EQ(store::sql::network_filesystem_name(0x58465342), nullptr);  // XFS
  EXPECT_EQ(store::sql::network_filesystem_name(0x01021994), nullptr);  // tmpfs
  TempDir dir;
  EXPECT_NO_THROW(store::sql::require_local_filesystem(dir / "meshmark.db"));
}

TEST(Durability, WriteAheadLogStaysBoundedWithCheckpointsUnderTheWriteLock) {
  TempDir dir;
  auto o = options(dir);
  o.synchronous_full = false;  // the fsyncs are not what this test is about
  auto s = store::open_sqlite_store(o);
  const std::string payload = R"({"pad":")" + std::string(3000, 'x') + R"("})";
  std::uintmax_t largest = 0;
  for (int i = 0; i < 4000; ++i) {  // about 12,000 pages written, one commit each
    store::JobSpec spec;
    spec.kind = "noop";
    spec.payload_json = payload;
    s->enqueue(spec);
    if (i % 100 == 99) largest = std::max(largest, std::filesystem::file_size(dir / "meshmark.db-wal"));
  }
  // Without checkpoints the log would hold every page (about 48 MB); checkpointed at 1000 pages it
  // is reused from the start and never grows far past 1000 pages of 4 KiB.
  EXPECT_LT(largest, 6u << 20) << "write-ahead log reached " << largest << " bytes";
  EXPECT_EQ(s->counts().available, 4000);
  EXPECT_TRUE(s->integrity_ok());
}
