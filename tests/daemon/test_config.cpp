// Config validation: every problem is reported with its key, defaults fill the rest.
#include <gtest/gtest.h>

#include <filesystem>

#include "service/config.h"

namespace mm::service {
namespace {

namespace fs = std::filesystem;

struct ConfigTest : ::testing::Test {
  void SetUp() override {
    dir = fs::temp_directory_path() / ("mm-config-" + std::to_string(::getpid()) + "-" +
                                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir);
    for (const char* d : {"home", "drop", "out"}) fs::create_directories(dir / d);
  }
  void TearDown() override { fs::remove_all(dir); }
  std::string expect_error(const std::string& text, bool check_folders = true) {
    try {
      parse_config(text, "test.json", dir.string(), check_folders);
    } catch (const ConfigError& e) {
      return e.what();
    }
    ADD_FAILURE() << "no error for " << text;
    return "";
  }
  fs::path dir;
  const std::string base = R"("home": "home", "drop_dir": "drop", "output_dir": "out")";
};

TEST_F(ConfigTest, MinimalConfigGetsDefaultsAndResolvesRelativePaths) {
  Config c = parse_config("{" + base + "}", "test.json", dir.string(), true);
  EXPECT_EQ(c.home, (dir / "home").string());
  EXPECT_EQ(c.drop_dir, (dir / "drop").string());
  EXPECT_EQ(c.workers, 2);
  EXPECT_EQ(c.p_threshold, 1e-9);
  EXPECT_EQ(c.watermark.message_bits, 32);
  EXPECT_EQ(c.context_cache_mb, 512);
  EXPECT_TRUE(c.compression.rail_quads);
  EXPECT_FALSE(c.compression.coarsen);
  EXPECT_EQ(c.fallback_angles, (std::vector<double>{30, 25, 20}));
  EXPECT_EQ(c.master_key_path(), (dir / "home" / "master.key").string());
}

TEST_F(ConfigTest, FullConfigParses) {
  Config c = parse_config("{" + base + R"(, "workers": 4, "lease_seconds": 60, "heartbeat_seconds": 10,
      "max_attempts": 3, "poll_interval_ms": 250, "settle_ms": 500, "use_inotify": false,
      "output_format": "ply", "shutdown_grace_seconds": 5, "log_level": "debug",
      "watermark": {"method": "multiplicative", "strength": 0.02, "threshold": 0.1, "message_bits": 48,
                    "max_vertices": 3000, "share": 0.3},
      "compression": {"tolerance": 0.01, "max_vertices": 400, "levels": 2, "angle": 40, "quads": false,
                      "coarsen": true, "stream_bits": 14, "fallback_angles": [32.5, 28]},
      "detect": {"p_threshold": 1e-9, "max_candidates": 5, "context_cache_mb": 0}})",
                          "test.json", dir.string(), true);
  EXPECT_EQ(c.workers, 4);
  EXPECT_EQ(c.compression.tolerance, 0.01);
  EXPECT_EQ(c.compression.max_vertices, 400);
  EXPECT_EQ(c.compression.levels, 2);
  EXPECT_EQ(c.compression.angle_degrees, 40);
  EXPECT_FALSE(c.compression.rail_quads);
  EXPECT_TRUE(c.compression.coarsen);
  EXPECT_EQ(c.stream_bits, 14);
  EXPECT_EQ(c.fallback_angles, (std::vector<double>{32.5, 28}));
  EXPECT_EQ(c.watermark.params.method, Method::Multiplicative);
  EXPECT_EQ(c.watermark.message_bits, 48);
  EXPECT_EQ(c.max_vertices, 3000);
  EXPECT_EQ(c.mark_share, 0.3);
  EXPECT_EQ(c.p_threshold, 1e-9);
  EXPECT_EQ(c.context_cache_mb, 0);
  EXPECT_FALSE(c.use_inotify);
  EXPECT_EQ(c.output_format, "ply");
}

TEST_F(ConfigTest, ReportsEveryProblemWithItsKey) {
  std::string e = expect_error(R"({"home": "home", "drop_dir": 5, "wokers": 2, "workers": "two",
      "watermark": {"strength": 2, "colour": "red", "share": 1}, "detect": {"p_threshold": 0.5, "context_cache_mb": -1}, "log_level": "loud",
      "compression": {"quads": "yes", "coarsen": 1}})");
  for (const char* s : {"test.json", "drop_dir: must be a string", "output_dir: missing", "wokers: unknown key",
                        "workers: must be an integer", "watermark.strength: must be in", "watermark.share: must be in",
                        "watermark.colour: unknown key", "detect.p_threshold: must be in", "detect.context_cache_mb: must be in [0, 1048576]", "log_level: must be one of",
                        "compression.quads: must be true or false", "compression.coarsen: must be true or false"})
    EXPECT_NE(e.find(s), std::string::npos) << s << "\n" << e;
}

TEST_F(ConfigTest, CadKeysSetTheTessellationAndTheCopyFormat) {
  Config c = parse_config("{" + base + R"(, "cad": {"linear_deflection": 0.001, "angular_deflection": 20,
      "copy_format": "glb"}})", "test.json", dir.string(), true);
  EXPECT_EQ(c.cad.linear_deflection, 0.001);
  EXPECT_EQ(c.cad.angular_deflection_degrees, 20);
  EXPECT_EQ(c.cad_copy_format, "glb");
  const Config d = parse_config("{" + base + "}", "test.json", dir.string(), true);
  EXPECT_EQ(d.cad_copy_format, "3mf");
  const std::string e = expect_error("{" + base + R"(, "cad": {"linear_deflection": 0, "angular_deflection": 100,
      "copy_format": "step", "quality": 1}})");
  for (const char* k : {"cad.linear_deflection: must be in", "cad.angular_deflection: must be in",
                        "cad.copy_format: must be one of", "cad.quality: unknown key"})
    EXPECT_NE(e.find(k), std::string::npos) << k << "\n" << e;
}

TEST_F(ConfigTest, MissingFoldersAndBadCombinations) {
  std::string e = expect_error(R"({"home": "nohome", "drop_dir": "drop", "output_dir": "drop/out"})");
  EXPECT_NE(e.find("home: folder"), std::string::npos) << e;
  EXPECT_NE(e.find("output_dir: must not lie inside drop_dir"), std::string::npos) << e;
  e = expect_error("{" + base + R"(, "watermark": {"max_vertices": 500}, "compression": {"max_vertices": 800, "levels": 9,
      "stream_bits": 8, "tolerance": 0, "shape": 1}})");
  for (const char* s : {"compression.max_vertices: must be at most watermark.max_vertices (500)",
                        "compression.levels: must be in", "compression.stream_bits: must be in",
                        "compression.tolerance: must be in", "compression.shape: unknown key"})
    EXPECT_NE(e.find(s), std::string::npos) << s << "\n" << e;
  for (const auto& [list, why] : {std::pair<const char*, const char*>{"30", "must be an array of numbers, got number"},
                                   {"[30, \"25\"]", "must hold numbers only, got string"},
                                   {"[30, 0]", "every value must be in (0, 180], got 0"},
                                   {"[181]", "every value must be in (0, 180], got 181"}}) {
    e = expect_error("{" + base + R"(, "compression": {"fallback_angles": )" + list + "}}");
    EXPECT_NE(e.find(std::string("compression.fallback_angles: ") + why), std::string::npos) << list << "\n" << e;
  }
  e = expect_error("{" + base + R"(, "lease_seconds": 10, "heartbeat_seconds": 6})");
  EXPECT_NE(e.find("heartbeat_seconds: must be at most half"), std::string::npos) << e;
  // Tools that only read settings do not need the folders.
  EXPECT_NO_THROW(parse_config(R"({"home": "nohome", "drop_dir": "d", "output_dir": "o"})", "t", dir.string(), false));
}

TEST_F(ConfigTest, NotJsonOrNotAnObject) {
  EXPECT_NE(expect_error("{ home: 1").find("not valid JSON"), std::string::npos);
  EXPECT_NE(expect_error("[1, 2]").find("must be a JSON object"), std::string::npos);
  // A number past double's range is nlohmann's out_of_range, not a parse_error: still a ConfigError.
  EXPECT_NE(expect_error(R"({"workers": 888e888})").find("not valid JSON"), std::string::npos);
  EXPECT_THROW(load_config((dir / "absent.json").string()), ConfigError);
}

TEST_F(ConfigTest, ChangesListOldAndNewValues) {
  Config a = parse_config("{" + base + "}", "t", dir.string(), true);
  Config b = parse_config("{" + base + R"(, "log_level": "debug", "workers": 3})", "t", dir.string(), true);
  auto ch = config_changes(a, b);
  ASSERT_EQ(ch.size(), 2u);
  EXPECT_EQ(ch[0], "log_level: info -> debug");
  EXPECT_EQ(ch[1], "workers: 2 -> 3");
  EXPECT_FALSE(needs_restart(ch[0]));
  EXPECT_TRUE(needs_restart(ch[1]));
  Config d = parse_config("{" + base + R"(, "compression": {"fallback_angles": []}})", "t", dir.string(), true);
  ch = config_changes(a, d);
  ASSERT_EQ(ch.size(), 1u);
  EXPECT_EQ(ch[0], "compression.fallback_angles: [30, 25, 20] -> []");
  EXPECT_FALSE(needs_restart(ch[0]));
}

// store.postgres selects the fleet's database; its password never shows in the change log.
TEST_F(ConfigTest, StorePostgresIsAConninfoShownWithoutItsPassword) {
  Config a = parse_config("{" + base + "}", "t", dir.string(), true);
  EXPECT_EQ(a.store_postgres, "");
  Config b = parse_config("{" + base + R"(, "store": {"postgres": "postgresql://mm:s3cret@db.example/meshmark"}})", "t",
                          dir.string(), true);
  EXPECT_EQ(b.store_postgres, "postgresql://mm:s3cret@db.example/meshmark");
  auto ch = config_changes(a, b);
  ASSERT_EQ(ch.size(), 1u);
  EXPECT_EQ(ch[0], "store.postgres:  -> postgresql://mm:***@db.example/meshmark");
  EXPECT_TRUE(needs_restart(ch[0]));
  Config c = parse_config("{" + base + R"(, "store": {"postgres": "host=db dbname=mm password='a b' user=mm"}})", "t",
                          dir.string(), true);
  ch = config_changes(a, c);
  ASSERT_EQ(ch.size(), 1u);
  EXPECT_EQ(ch[0].find("a b"), std::string::npos) << ch[0];
  EXPECT_NE(ch[0].find("password=*** user=mm"), std::string::npos) << ch[0];
  const std::string e = expect_error("{" + base + R"(, "store": {"postgres": 5, "sqlite": "x"}})");
  for (const char* s : {"store.postgres: must be a string", "store.sqlite: unknown key"})
    EXPECT_NE(e.find(s), std::string::npos) << s << "\n" << e;
  EXPECT_NE(expect_error("{" + base + R"(, "store": {"postgres": ""}})").find("store.postgres: must name"),
            std::string::npos);
}

TEST(ConfigExample, ShippedExampleIsValid) {
  Config c = load_config(std::string(MESHMARK_SOURCE_DIR) + "/config/meshmark.example.json", false);
  EXPECT_GE(c.workers, 1);
}

}  // namespace
}  // namespace mm::service
