// The store-facing `meshmark` commands, run in-process on a temporary home.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cstdio>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "store/home.h"
#include "store_test_util.h"

using namespace mm;
using namespace mm::test;
using nlohmann::json;

namespace {

// Runs `meshmark <args>` with only the store commands registered; returns stdout.
std::string run(std::vector<std::string> args) {
  CLI::App app{"meshmark"};
  app.require_subcommand(1);
  cli::add_store_commands(app);
  std::vector<const char*> argv = {"meshmark"};
  for (auto& a : args) argv.push_back(a.c_str());
  testing::internal::CaptureStdout();
  try {
    app.parse(static_cast<int>(argv.size()), argv.data());
  } catch (...) {
    std::fflush(stdout);
    testing::internal::GetCapturedStdout();
    throw;
  }
  std::fflush(stdout);
  return testing::internal::GetCapturedStdout();
}

int exit_code_of(std::vector<std::string> args, std::string* message = nullptr) {
  try {
    run(std::move(args));
    return 0;
  } catch (const cli::CommandFailed& e) {
    if (message) *message = e.what();
    return e.code;
  }
}

struct CliHome {
  TempDir dir;
  std::string home = dir / "home";
  CliHome() { ::unsetenv(keys::kMasterKeyEnv); }
  json j(std::vector<std::string> args) {
    args.push_back("--home");
    args.push_back(home);
    args.push_back("--json");
    return json::parse(run(args));
  }
};

}  // namespace

TEST(Cli, InitCreatesHomeWithOwnerOnlyMasterKeyAndIsIdempotent) {
  CliHome h;
  auto first = h.j({"init"});
  EXPECT_TRUE(first["created"].get<bool>());
  EXPECT_EQ(first["schema_version"].get<int>(), store::open_home(store::resolve_home(h.home), false)->schema_version());
  struct stat st {};
  ASSERT_EQ(::stat((h.home + "/master.key").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  ASSERT_EQ(::stat(h.home.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0700u);
  auto second = h.j({"init"});
  EXPECT_FALSE(second["created"].get<bool>());
  std::string human = run({"init", "--home", h.home});
  EXPECT_NE(human.find("already initialized"), std::string::npos) << human;
}

TEST(Cli, CustomersAddListRotate) {
  CliHome h;
  h.j({"init"});
  auto acme = h.j({"customer", "add", "acme"});
  EXPECT_EQ(acme["name"], "acme");
  EXPECT_EQ(acme["key_version"], 1);
  h.j({"customer", "add", "globex"});
  auto list = h.j({"customer", "list"});
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[1]["name"], "globex");
  auto rot = h.j({"customer", "rotate-key", "acme"});
  EXPECT_EQ(rot["key_version"], 2);
  EXPECT_EQ(h.j({"customer", "list"})[0]["key_version"], 2);
  std::string msg;
  EXPECT_EQ(exit_code_of({"customer", "add", "acme", "--home", h.home}, &msg), 1);
  EXPECT_NE(msg.find("already exists"), std::string::npos) << msg;
  EXPECT_EQ(exit_code_of({"customer", "rotate-key", "nobody", "--home", h.home}, &msg), 1);
  EXPECT_NE(msg.find("nobody"), std::string::npos) << msg;
  EXPECT_EQ(exit_code_of({"customer", "add", "../evil", "--home", h.home}, &msg), 1);
  std::string human = run({"customer", "list", "--home", h.home});
  EXPECT_NE(human.find("acme"), std::string::npos);
  EXPECT_NE(human.find("key v2"), std::string::npos) << human;
}

TEST(Cli, TokensCreateListRevokeAndTheTokenIsShownOnce) {
  CliHome h;
  h.j({"init"});
  auto t = h.j({"token", "create", "pdm", "--role", "submit"});
  const std::string secret = t["token"].get<std::string>();
  EXPECT_EQ(secret.rfind("mmt_", 0), 0u);
  EXPECT_EQ(t["role"], "submit");
  auto list = h.j({"token", "list"});
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0]["name"], "pdm");
  EXPECT_TRUE(list[0]["revoked_at"].is_null());
  EXPECT_EQ(list.dump().find(secret.substr(4)), std::string::npos) << "list never shows a token";
  EXPECT_EQ(run({"token", "list", "--home", h.home}).find(secret.substr(4)), std::string::npos);
  std::string msg;
  EXPECT_EQ(exit_code_of({"token", "create", "pdm", "--home", h.home}, &msg), 1);
  EXPECT_NE(msg.find("already exists"), std::string::npos) << msg;
  EXPECT_EQ(h.j({"token", "revoke", "pdm"})["revoked"], true);
  EXPECT_FALSE(h.j({"token", "list"})[0]["revoked_at"].is_null());
  EXPECT_EQ(exit_code_of({"token", "revoke", "pdm", "--home", h.home}, &msg), 1);
  EXPECT_NE(msg.find("no live token"), std::string::npos) << msg;
  EXPECT_THROW(run({"token", "create", "x", "--role", "root", "--home", h.home}), CLI::ParseError);
  EXPECT_FALSE(store::open_home(store::resolve_home(h.home), false)->token_for_secret(secret).has_value());
}

TEST(Cli, RefusesAMasterKeyOthersCanRead) {
  CliHome h;
  h.j({"init"});
  ::chmod((h.home + "/master.key").c_str(), 0644);
  std::string msg;
  EXPECT_EQ(exit_code_of({"customer", "add", "acme", "--home", h.home}, &msg), 1);
  EXPECT_NE(msg.find("chmod 600"), std::string::npos) << msg;
  EXPECT_EQ(h.j({"customer", "list"}).size(), 0u) << "listing needs no key and nothing was added";
}

TEST(Cli, MissingHomeSaysToRunInit) {
  TempDir dir;
  std::string msg;
  EXPECT_EQ(exit_code_of({"jobs", "list", "--home", dir / "nothing-here"}, &msg), 1);
  EXPECT_NE(msg.find("meshmark init"), std::string::npos) << msg;
}

TEST(Cli, JobsListShowCancelRetry) {
  CliHome h;
  h.j({"init"});
  std::int64_t a = 0, b = 0;
  {
    auto s = store::open_home(store::resolve_home(h.home), false);
    a = s->enqueue({"protect", R"({"file":"x.stl"})", 0, 3, "", {}}).job.id;
    b = s->enqueue({"detect", "{}", 5, 3, "", {}}).job.id;
    auto j = s->claim("w", 60'000, {"detect"});
    s->fail(j->id, "w", "bad suspect file", false);
  }
  auto list = h.j({"jobs", "list"});
  EXPECT_EQ(list["counts"]["available"], 1);
  EXPECT_EQ(list["counts"]["discarded"], 1);
  ASSERT_EQ(list["jobs"].size(), 2u);
  auto only = h.j({"jobs", "list", "--state", "discarded"});
  ASSERT_EQ(only["jobs"].size(), 1u);
  EXPECT_EQ(only["jobs"][0]["id"], b);
  EXPECT_EQ(only["jobs"][0]["errors"][0]["error"], "bad suspect file");
  auto show = h.j({"jobs", "show", std::to_string(a)});
  EXPECT_EQ(show["payload"]["file"], "x.stl");
  EXPECT_EQ(show["state"], "available");
  EXPECT_EQ(h.j({"jobs", "cancel", std::to_string(a)})["state"], "cancelled");
  EXPECT_EQ(h.j({"jobs", "retry", std::to_string(a)})["state"], "available");
  EXPECT_EQ(h.j({"jobs", "retry", std::to_string(b)})["state"], "available");
  std::string msg;
  EXPECT_EQ(exit_code_of({"jobs", "retry", std::to_string(a), "--home", h.home}, &msg), 1);
  EXPECT_NE(msg.find("available"), std::string::npos) << msg;
  EXPECT_EQ(exit_code_of({"jobs", "show", "999", "--home", h.home}, &msg), 1);
  EXPECT_THROW(run({"jobs", "list", "--state", "bogus", "--home", h.home}), CLI::ParseError);
  std::string human = run({"jobs", "show", std::to_string(b), "--home", h.home});
  EXPECT_NE(human.find("bad suspect file"), std::string::npos) << human;
}

TEST(Cli, AssetsCopiesDetections) {
  CliHome h;
  h.j({"init"});
  {
    auto s = store::open_home(store::resolve_home(h.home), true);
    auto c = s->add_customer("acme");
    auto a = s->put_asset_bytes({1, 2, 3}, "bracket.stl");
    store::NewCopy nc;
    nc.asset_id = a.id;
    nc.customer_id = c.id;
    nc.key_version = 1;
    nc.nonce = std::vector<std::uint8_t>(24, 0xab);
    nc.payload_hex = "c0ffee";
    auto copy = s->issue_copy(nc);
    store::NewDetection d;
    d.suspect_sha256 = a.sha256;
    d.suspect_name = "leak.stl";
    d.verdict = "attributed";
    d.customer_id = c.id;
    d.copy_id = copy.id;
    d.p_value = 1e-15;
    s->record_detection(d);
  }
  auto assets = h.j({"assets"});
  ASSERT_EQ(assets.size(), 1u);
  EXPECT_EQ(assets[0]["name"], "bracket.stl");
  auto copies = h.j({"copies", "--asset", assets[0]["sha256"].get<std::string>()});
  ASSERT_EQ(copies.size(), 1u);
  EXPECT_EQ(copies[0]["payload_hex"], "c0ffee");
  EXPECT_EQ(copies[0]["nonce"], [] { std::string s; for (int i = 0; i < 24; ++i) s += "ab"; return s; }());
  EXPECT_EQ(h.j({"copies", "--asset", std::to_string(assets[0]["id"].get<int>())}).size(), 1u);
  auto dets = h.j({"detections"});
  ASSERT_EQ(dets.size(), 1u);
  EXPECT_EQ(dets[0]["verdict"], "attributed");
  EXPECT_DOUBLE_EQ(dets[0]["p_value"].get<double>(), 1e-15);
  std::string human = run({"detections", "--home", h.home});
  EXPECT_NE(human.find("acme"), std::string::npos) << human;
  EXPECT_NE(human.find("1e-15"), std::string::npos) << human;
  std::string msg;
  EXPECT_EQ(exit_code_of({"copies", "--asset", "12345", "--home", h.home}, &msg), 1);
}
