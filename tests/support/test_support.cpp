// Atomic file writes, hex and SHA-256: the plumbing every writer and every content address uses.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

#include "common/temp_dir.h"
#include "support/atomic_file.h"
#include "support/hex.h"
#include "support/sha256.h"

namespace mm::support {
namespace {

namespace fs = std::filesystem;

// A fresh folder per test under the program's scratch folder.
struct Folder {
  fs::path dir;
  Folder() {
    static int n = 0;
    dir = test::scratch_dir("mm_support") / std::to_string(++n);
    fs::create_directories(dir);
  }
  const fs::path& path() const { return dir; }
};

std::string read(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::vector<std::string> names_in(const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) out.push_back(e.path().filename().string());
  std::sort(out.begin(), out.end());
  return out;
}

TEST(AtomicFile, WritesReplacesAndLeavesNoTemporary) {
  Folder dir;
  const fs::path p = dir.path() / "part.stl";
  write_file_atomic(p.string(), std::string_view("first"), 0640);
  EXPECT_EQ(read(p), "first");
  struct stat st {};
  ASSERT_EQ(::stat(p.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0640u);
  write_file_atomic(p.string(), std::vector<std::uint8_t>{'s', 'e', 'c', 'o', 'n', 'd'});
  EXPECT_EQ(read(p), "second");
  EXPECT_EQ(names_in(dir.path()), std::vector<std::string>{"part.stl"});
}

TEST(AtomicFile, AnExclusiveWriteNeverReplaces) {
  Folder dir;
  const fs::path p = dir.path() / "master.key";
  EXPECT_TRUE(write_file_exclusive(p.string(), "secret"));
  EXPECT_FALSE(write_file_exclusive(p.string(), "other"));
  EXPECT_EQ(read(p), "secret");
  EXPECT_EQ(names_in(dir.path()), std::vector<std::string>{"master.key"});
}

TEST(AtomicFile, AFailureKeepsItsErrnoAndLeavesNothing) {
  Folder dir;
  const fs::path p = dir.path() / "missing" / "x.mmc";
  try {
    write_file_atomic(p.string(), std::string_view("x"));
    FAIL() << "no error";
  } catch (const std::system_error& e) {
    EXPECT_EQ(e.code().value(), ENOENT);
    EXPECT_NE(std::string(e.what()).find("cannot create temporary file"), std::string::npos) << e.what();
  }
  // A folder in place of the target: the rename fails and the temporary is removed.
  fs::create_directory(dir.path() / "taken");
  fs::create_directory(dir.path() / "taken" / "inside");
  EXPECT_THROW(write_file_atomic((dir.path() / "taken").string(), std::string_view("x")), std::system_error);
  EXPECT_EQ(names_in(dir.path()), std::vector<std::string>{"taken"});
}

TEST(AtomicFile, TemporariesAreRecognisedByName) {
  EXPECT_TRUE(is_atomic_write_temporary(".part-0a1b2c3d4e5f.mmc.tmp.AbC123"));
  EXPECT_FALSE(is_atomic_write_temporary("part.mmc.tmp.AbC123"));   // not hidden
  EXPECT_FALSE(is_atomic_write_temporary(".part.mmc.tmp.AbC12"));   // not mkstemp's six
  EXPECT_FALSE(is_atomic_write_temporary(".part.mmc"));
}

TEST(Hex, RoundTripsAndRefusesWhatIsNotHex) {
  const std::vector<std::uint8_t> bytes{0x00, 0x7f, 0xa5, 0xff};
  EXPECT_EQ(to_hex(bytes.data(), bytes.size()), "007fa5ff");
  EXPECT_EQ(from_hex("007fa5ff"), bytes);
  EXPECT_EQ(from_hex("007FA5FF"), bytes);
  EXPECT_THROW(from_hex("abc"), std::invalid_argument);
  EXPECT_THROW(from_hex("zz"), std::invalid_argument);
}

TEST(Sha256, MatchesTheStandardVectorInMemoryAndOnDisk) {
  const std::string abc = "abc";
  const std::string expected = "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad";
  EXPECT_EQ(sha256_hex(abc.data(), abc.size()), expected);
  Sha256 pieces;
  pieces.update("a", 1);
  pieces.update("bc", 2);
  EXPECT_EQ(pieces.hex(), expected);
  Folder dir;
  const fs::path p = dir.path() / "abc";
  write_file_atomic(p.string(), abc);
  EXPECT_EQ(sha256_file_hex(p.string()), expected);
  EXPECT_THROW(sha256_file_hex((dir.path() / "absent").string()), std::system_error);
}

}  // namespace
}  // namespace mm::support
