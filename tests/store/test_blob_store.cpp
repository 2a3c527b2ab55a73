#include <gtest/gtest.h>
#include <sys/stat.h>
#include <utime.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "store/blob_store.h"
#include "support/sha256.h"
#include "store_test_util.h"

using namespace mm;
using namespace mm::test;
namespace fs = std::filesystem;

namespace {
// Every regular file under root except tmp/: must be named by its own verified hash.
std::vector<std::string> blob_files(const std::string& root) {
  std::vector<std::string> out;
  for (auto& e : fs::recursive_directory_iterator(root)) {
    if (!e.is_regular_file()) continue;
    if (e.path().parent_path().filename() == "tmp") continue;
    out.push_back(e.path().string());
  }
  return out;
}
std::size_t temp_files(const std::string& root) {
  std::size_t n = 0;
  for (auto& e : fs::directory_iterator(root + "/tmp")) n += e.is_regular_file();
  return n;
}
}  // namespace

TEST(BlobStore, PutGetVerifiesContentAddress) {
  TempDir dir;
  store::FsBlobStore b(dir / "blobs");
  std::string h = b.put(std::string("hello"));
  // sha256("hello")
  EXPECT_EQ(h, "2cf24dba5fb0a30e26e83b2ac5b9e29e1b161e5c1fa7425e73043362938b9824");
  EXPECT_TRUE(b.contains(h));
  EXPECT_EQ(b.size(h), 5u);
  auto bytes = b.get(h);
  EXPECT_EQ(std::string(bytes.begin(), bytes.end()), "hello");
  EXPECT_EQ(b.put(std::string("hello")), h) << "same bytes, same address";
  EXPECT_EQ(blob_files(b.root()).size(), 1u);
  EXPECT_EQ(b.path(h), b.root() + "/2c/" + h);
  EXPECT_EQ(b.put(std::string()), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
}

TEST(BlobStore, PutFileStreamsLargeFilesAndLeavesNoTempFiles) {
  TempDir dir;
  store::FsBlobStore b(dir / "blobs");
  std::mt19937 rng(7);
  std::string data(3 * 1024 * 1024 + 17, '\0');
  for (auto& c : data) c = static_cast<char>(rng());
  std::string src = dir / "big.bin";
  std::ofstream(src, std::ios::binary).write(data.data(), static_cast<std::streamsize>(data.size()));
  std::string h = b.put_file(src);
  EXPECT_EQ(h, support::sha256_file_hex(src));
  EXPECT_EQ(h, support::sha256_hex(reinterpret_cast<const std::uint8_t*>(data.data()), data.size()));
  EXPECT_EQ(b.put_file(src), h);
  EXPECT_EQ(temp_files(b.root()), 0u) << "the duplicate put must remove its temporary copy";
  for (auto& f : blob_files(b.root()))
    EXPECT_EQ(fs::path(f).filename().string(), support::sha256_file_hex(f)) << f;
  EXPECT_THROW(b.put_file(dir / "does-not-exist"), store::BlobError);
  EXPECT_EQ(temp_files(b.root()), 0u);
}

TEST(BlobStore, CorruptionAndMissingBlobsAreReportedNotReturned) {
  TempDir dir;
  store::FsBlobStore b(dir / "blobs");
  std::string h = b.put(std::string("original bytes"));
  std::string p = b.path(h);
  ::chmod(p.c_str(), 0600);
  std::ofstream(p, std::ios::binary | std::ios::in | std::ios::out).write("X", 1);
  try {
    b.get(h);
    FAIL() << "corrupted blob returned";
  } catch (const store::BlobError& e) {
    EXPECT_NE(std::string(e.what()).find("corrupted"), std::string::npos) << e.what();
  }
  std::string missing(64, 'b');
  EXPECT_FALSE(b.contains(missing));
  EXPECT_THROW(b.get(missing), store::BlobError);
  EXPECT_THROW(b.size(missing), store::BlobError);
  // Names that are not a sha256 never become paths (no ../ escapes).
  EXPECT_THROW(b.path("../../etc/passwd"), store::BlobError);
  EXPECT_THROW(b.get("ABCDEF"), store::BlobError);
  EXPECT_FALSE(store::is_sha256_hex(std::string(64, 'G')));
}

TEST(BlobStore, StaleTempFilesFromACrashAreRemovedOnOpen) {
  TempDir dir;
  std::string root = dir / "blobs";
  { store::FsBlobStore b(root); }
  std::string stale = root + "/tmp/leftover";
  std::ofstream(stale) << "half a file";
  struct utimbuf old {1000, 1000};
  ::utime(stale.c_str(), &old);
  std::string young = root + "/tmp/in-flight";
  std::ofstream(young) << "another process is writing this";
  store::FsBlobStore b(root);
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(young)) << "a young temp file may belong to a live writer";
  EXPECT_TRUE(blob_files(root).empty()) << "temp files are never blobs";
}

TEST(BlobStore, BlobsAreReadOnlyOnDisk) {
  TempDir dir;
  store::FsBlobStore b(dir / "blobs");
  std::string h = b.put(std::string("x"));
  struct stat st {};
  ASSERT_EQ(::stat(b.path(h).c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0400u);
}
