// Drop folders: path safety (symlinks, escapes, temporary names) and completeness detection.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "service/drop_watcher.h"

namespace mm::service {
namespace {

namespace fs = std::filesystem;

std::int64_t now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

struct DropTest : ::testing::Test {
  void SetUp() override {
    root = fs::temp_directory_path() / ("mm-drop-" + std::to_string(::getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root);
    fs::create_directories(root / "protect" / "acme");
    fs::create_directories(root / "detect");
    fs::create_directories(root.string() + "-outside");
  }
  void TearDown() override {
    fs::remove_all(root);
    fs::remove_all(root.string() + "-outside");
  }
  void write(const fs::path& p, const std::string& text = "OFF\n") { std::ofstream(p) << text; }
  std::vector<std::string> names(const std::vector<DropItem>& items) {
    std::vector<std::string> n;
    for (const auto& i : items) n.push_back(i.relative);
    std::sort(n.begin(), n.end());
    return n;
  }
  fs::path root;
};

TEST(DropNames, IgnoredAndCustomerNames) {
  for (const char* n : {".hidden.stl", "part.stl.tmp", "part.part", "part.stl~", ".part.stl.swp", "x.crdownload", "#a#", ""})
    EXPECT_TRUE(is_ignored_name(n)) << n;
  for (const char* n : {"part.stl", "fandisk_quads.off", "a.b.c.obj"}) EXPECT_FALSE(is_ignored_name(n)) << n;
  EXPECT_TRUE(is_valid_customer_name("acme-2_b.c"));
  // std::string elements: a c_str() of a temporary in the list would dangle inside the loop.
  for (const std::string& n : {std::string(), std::string(".acme"), std::string("ac me"), std::string("a/b"),
                               std::string(".."), std::string(65, 'a')})
    EXPECT_FALSE(is_valid_customer_name(n)) << n;
}

TEST_F(DropTest, ClassifiesOnlySafeRegularFiles) {
  write(root / "protect/acme/part.stl");
  write(root / "detect/suspect.off");
  write(root.string() + "-outside/secret.stl");
  auto p = classify_drop_path(root.string(), "protect/acme/part.stl");
  ASSERT_TRUE(p);
  EXPECT_EQ(p->kind, DropKind::protect);
  EXPECT_EQ(p->customer, "acme");
  EXPECT_EQ(p->name, "part.stl");
  auto d = classify_drop_path(root.string(), "detect/suspect.off");
  ASSERT_TRUE(d);
  EXPECT_EQ(d->kind, DropKind::detect);

  std::string why;
  for (const char* bad : {"../x-outside/secret.stl", "protect/../detect/suspect.off", "protect/acme/../../x",
                          "/etc/passwd", "protect/acme", "protect/acme/sub/part.stl", "other/part.stl",
                          "detect/", "protect//part.stl", "detect/./suspect.off"}) {
    EXPECT_FALSE(classify_drop_path(root.string(), bad, &why)) << bad;
    EXPECT_FALSE(why.empty()) << bad;
  }
  // Symlinks: to a file outside, and a customer folder that is a symlink to elsewhere.
  fs::create_symlink(root.string() + "-outside/secret.stl", root / "protect/acme/link.stl");
  EXPECT_FALSE(classify_drop_path(root.string(), "protect/acme/link.stl", &why));
  EXPECT_NE(why.find("not a regular file"), std::string::npos) << why;
  fs::create_directory_symlink(root.string() + "-outside", root / "protect/evil");
  EXPECT_FALSE(classify_drop_path(root.string(), "protect/evil/secret.stl", &why));
  EXPECT_NE(why.find("symlink"), std::string::npos) << why;
  // A folder is not a file.
  fs::create_directories(root / "detect/folder.stl");
  EXPECT_FALSE(classify_drop_path(root.string(), "detect/folder.stl"));
}

TEST_F(DropTest, InotifyTakesRenamedFilesAtOnceAndWrittenFilesOnceSettledAfterTheirLastClose) {
  DropWatcher w(root.string(), true, 300);
  if (!w.inotify_active()) GTEST_SKIP() << "inotify unavailable here";
  const std::int64_t t = now_ms();  // polls pretend time moves on from here
  std::ofstream open_file(root / "protect/acme/slow.stl");
  open_file << "solid x\n" << std::flush;
  EXPECT_TRUE(w.poll(t).empty());
  EXPECT_TRUE(w.poll(t + 2000).empty()) << "never while still open, however long";
  // Appended in several open-write-close rounds: not taken at the first close.
  { std::ofstream(root / "detect/parts.stl") << "solid a\n"; }
  write(root / "detect/.hidden.off");
  EXPECT_TRUE(w.poll(t + 2000).empty());
  { std::ofstream(root / "detect/parts.stl", std::ios::app) << "facet\n"; }
  EXPECT_TRUE(w.poll(t + 2200).empty()) << "changed since: the settle time restarts";
  { std::ofstream(root / "detect/parts.stl", std::ios::app) << "endsolid a\n"; }
  EXPECT_TRUE(w.poll(t + 2400).empty());
  EXPECT_EQ(names(w.poll(t + 3000)), std::vector<std::string>{"detect/parts.stl"});
  open_file.close();
  EXPECT_TRUE(w.poll(t + 3000).empty());
  EXPECT_EQ(names(w.poll(t + 4000)), std::vector<std::string>{"protect/acme/slow.stl"});
  // A new customer folder is watched as it appears; a file renamed in is ready at once.
  fs::create_directories(root / "protect/newco");
  w.poll(t + 4000);
  write(root / "protect/newco/part.off.part");
  EXPECT_TRUE(w.poll(t + 4000).empty());  // temporary name
  fs::rename(root / "protect/newco/part.off.part", root / "protect/newco/part.off");
  EXPECT_EQ(names(w.poll(t + 4000)), std::vector<std::string>{"protect/newco/part.off"});
  // Reported once until forgotten.
  EXPECT_TRUE(w.poll(t + 9000).empty());
}

TEST_F(DropTest, PollingWaitsUntilFilesAreStable) {
  write(root / "detect/a.off");
  DropWatcher w(root.string(), false, 300);
  EXPECT_FALSE(w.inotify_active());
  std::int64_t t0 = now_ms() + 1000;  // pretend time moves; the file's mtime is "old" after 300 ms
  EXPECT_TRUE(w.poll(t0).empty());     // first sighting
  EXPECT_TRUE(w.poll(t0 + 100).empty());
  // It grows: the clock restarts.
  { std::ofstream(root / "detect/a.off", std::ios::app) << "more\n"; }
  auto t1 = now_ms() + 1000;
  EXPECT_TRUE(w.poll(t1).empty());
  auto ready = w.poll(t1 + 400);
  ASSERT_EQ(names(ready), std::vector<std::string>{"detect/a.off"});
  EXPECT_TRUE(w.poll(t1 + 800).empty());
  w.forget(ready[0].path);
  EXPECT_TRUE(w.poll(t1 + 1200).empty());  // seen again after forget: settles again
  EXPECT_EQ(w.poll(t1 + 1700).size(), 1u);
}

TEST_F(DropTest, FinishMovesWithReasonAndNeverOverwrites) {
  write(root / "protect/acme/part.stl", "one");
  auto item = *classify_drop_path(root.string(), "protect/acme/part.stl");
  auto dest = DropWatcher::finish(root.string(), item, false, R"({"reason": "bad"})");
  EXPECT_EQ(dest, (root / "failed/protect/acme/part.stl").string());
  EXPECT_FALSE(fs::exists(root / "protect/acme/part.stl"));
  std::ifstream j(dest + ".json");
  std::string text((std::istreambuf_iterator<char>(j)), {});
  EXPECT_EQ(text, R"({"reason": "bad"})");
  write(root / "protect/acme/part.stl", "two");
  item = *classify_drop_path(root.string(), "protect/acme/part.stl");
  dest = DropWatcher::finish(root.string(), item, false, "{}");
  EXPECT_EQ(dest, (root / "failed/protect/acme/part-1.stl").string());
  std::ifstream first(root / "failed/protect/acme/part.stl");
  std::string one((std::istreambuf_iterator<char>(first)), {});
  EXPECT_EQ(one, "one");
}

}  // namespace
}  // namespace mm::service
