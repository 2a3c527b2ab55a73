// Evidence packages as a legal team gets them: `meshmark evidence` on a detection made by
// `meshmark run`, `meshmark verify` on the package, and every way of tampering with it failing
// with a message that names what failed. The report is opened in headless Chromium when it is
// installed (scripts/install-deps.sh installs it; under CI its absence fails the test).
#include <gtest/gtest.h>
#include <png.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <map>
#include <nlohmann/json.hpp>

#include "cli/cli_test_util.h"
#include "service/evidence_package.h"

namespace {

using namespace mm::test;
using nlohmann::json;

bool under_ci() {
  const char* ci = std::getenv("CI");
  return ci && std::string(ci) == "true";
}

bool chromium_installed() { return std::system("command -v chromium >/dev/null 2>&1") == 0; }

// One protected part, two customers, bob's copy leaked after smoothing, detected: shared by the
// tests (each copies the package before changing it).
class Evidence : public ::testing::Test {
 protected:
  static Scratch* s;
  static std::string home, package, leak, copy_off;
  static std::int64_t detection;

  static void SetUpTestSuite() {
    s = new Scratch();
    home = *s / "home";
    package = *s / "package";
    leak = *s / "leak.off";
    const std::string cfg = *s / "meshmarkd.json";
    std::ofstream(cfg) << R"({"home": "home", "drop_dir": "drop", "output_dir": "out", "workers": 2,
                              "log_level": "warn", "output_format": "off",
                              "evidence": {"auto": true, "pdf": false}})";
    fs::create_directories(*s / "drop");
    fs::create_directories(*s / "out");
    ASSERT_EQ(meshmark(*s, {"init", "--home", home}).code, 0);
    ASSERT_EQ(meshmark(*s, {"customer", "add", "alice", "--home", home}).code, 0);
    ASSERT_EQ(meshmark(*s, {"customer", "add", "bob", "--home", home}).code, 0);
    ASSERT_EQ(meshmark(*s, {"sample", "chamfered_block", *s / "part.off"}).code, 0);
    for (const char* c : {"alice", "bob"})
      ASSERT_EQ(meshmark(*s, {"submit", "protect", *s / "part.off", "--customer", c, "--config", cfg}).code, 0);
    auto run = meshmark(*s, {"run", "--until-empty", "--no-drops", "--config", cfg});
    ASSERT_EQ(run.code, 0) << run.err;
    for (const auto& e : fs::directory_iterator(*s / "out/bob"))
      if (e.path().extension() == ".off") copy_off = e.path().string();
    ASSERT_FALSE(copy_off.empty());
    ASSERT_EQ(meshmark(*s, {"attack", "noise", "-A", "0.001", "--seed", "3", copy_off, leak}).code, 0);
    ASSERT_EQ(meshmark(*s, {"submit", "detect", leak, "--config", cfg}).code, 0);
    run = meshmark(*s, {"run", "--until-empty", "--no-drops", "--config", cfg});
    ASSERT_EQ(run.code, 0) << run.err;
    const auto dets = meshmark(*s, {"detections", "--home", home, "--json"});
    const json d = json::parse(dets.out);
    ASSERT_EQ(d.size(), 1u);
    ASSERT_EQ(d[0]["verdict"], "attributed") << dets.out;
    detection = d[0]["id"].get<std::int64_t>();
    const auto ev = meshmark(*s, {"evidence", std::to_string(detection), package, "--home", home});
    ASSERT_EQ(ev.code, 0) << ev.err;
    const auto pub = meshmark(*s, {"evidence", "pubkey", "--home", home});
    ASSERT_EQ(pub.code, 0) << pub.err;
    std::ofstream(*s / "pub.txt") << pub.out;
  }
  static void TearDownTestSuite() { delete s; }

  // A copy of the package to tamper with.
  std::string copy_package(const std::string& name) {
    const std::string dst = *s / name;
    fs::remove_all(dst);
    fs::copy(package, dst, fs::copy_options::recursive);
    return dst;
  }
};
Scratch* Evidence::s = nullptr;
std::string Evidence::home, Evidence::package, Evidence::leak, Evidence::copy_off;
std::int64_t Evidence::detection = 0;

TEST(Dsse, PreAuthenticationEncodingFollowsTheSpec) {
  // The DSSE protocol's own example.
  EXPECT_EQ(mm::service::dsse_pae("http://example.com/HelloWorld", "hello world"),
            "DSSEv1 29 http://example.com/HelloWorld 11 hello world");
}

TEST_F(Evidence, PackageHoldsTheStatementItsSignatureAndTheReport) {
  for (const char* f : {"statement.json", "statement.dsse.json", "report.html"})
    EXPECT_TRUE(exists(package + "/" + f)) << f;
  const json st = json::parse(slurp(package + "/statement.json"));
  EXPECT_EQ(st["_type"], "https://in-toto.io/Statement/v1");
  const json& p = st["predicate"];
  ASSERT_EQ(p["attributed"].size(), 1u);
  EXPECT_EQ(p["attributed"][0]["customer"], "bob");
  EXPECT_GT(p["attributed"][0]["neg_log10_corrected_p"].get<double>(), 9);
  EXPECT_EQ(p["attributed"][0]["key"]["version"], 1);
  EXPECT_EQ(p["copies"].size(), 2u) << "both copies of the part tried and reported";
  EXPECT_EQ(p["method"]["false_attribution"]["false_attributions"], 0);
  EXPECT_GE(p["method"]["false_attribution"]["trials"].get<int>(), 1000);
  EXPECT_EQ(p["meshmark"]["build_sha256"].get<std::string>().size(), 64u);
  EXPECT_EQ(p["timestamp"]["requested"], false);
  // The chain runs from the original's intake through the copy's issue to the detection.
  std::vector<std::string> actions;
  for (const auto& e : p["chain"]) actions.push_back(e["action"]);
  ASSERT_FALSE(actions.empty());
  EXPECT_EQ(actions.front(), "asset.intake");
  EXPECT_NE(std::find(actions.begin(), actions.end(), "copy.issue"), actions.end());
  EXPECT_EQ(actions.back(), "detection.record");
  // Subjects: the report by digest, and the suspect, original, issued stream and copy.
  std::set<std::string> roles;
  for (const auto& sub : st["subject"]) roles.insert(sub["name"].get<std::string>().substr(0, sub["name"].get<std::string>().find('/')));
  for (const char* r : {"report.html", "suspect", "original", "issued-stream", "issued-copy"}) EXPECT_TRUE(roles.count(r)) << r;
  // Plain words on the first screen.
  const std::string html = slurp(package + "/report.html");
  EXPECT_NE(html.find("is a copy of part"), std::string::npos);
  EXPECT_NE(html.find("customer <span class=\"customer\">bob</span>"), std::string::npos);
  EXPECT_NE(html.find("less than once in 10^"), std::string::npos);
  EXPECT_NE(html.find("data:image/png;base64,"), std::string::npos);
}

TEST_F(Evidence, VerifiesWithTheExportedKeyAndWithTheHome) {
  auto r = meshmark(*s, {"verify", package, "--pubkey", *s / "pub.txt", "--file", leak});
  EXPECT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("ok      signature: valid"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ok      suspect/leak.off"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ok      issued-copy/"), std::string::npos) << r.out;
  r = meshmark(*s, {"verify", package, "--home", home});
  EXPECT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("ok      original/part.off: in the blob store"), std::string::npos) << r.out;
}

TEST_F(Evidence, AnyFlippedByteOfThePackageFailsNamingWhatFailed) {
  std::vector<std::pair<std::string, std::string>> cases = {{"report.html", "report.html: SHA-256 differs"},
                                                            {"statement.json", "statement.json: differs"},
                                                            {"statement.dsse.json", ""}};
  if (exists(package + "/report.pdf")) cases.push_back({"report.pdf", "report.pdf: SHA-256 differs"});
  for (const auto& [file, message] : cases) {
    for (double at : {0.1, 0.5, 0.9}) {
      const std::string dir = copy_package("tampered");
      std::string bytes = slurp(dir + "/" + file);
      const std::size_t i = static_cast<std::size_t>(at * static_cast<double>(bytes.size()));
      bytes[i] = static_cast<char>(bytes[i] ^ 0x01);
      std::ofstream(dir + "/" + file, std::ios::binary | std::ios::trunc) << bytes;
      const auto r = meshmark(*s, {"verify", dir, "--pubkey", *s / "pub.txt"});
      EXPECT_EQ(r.code, 1) << file << " byte " << i << ":\n" << r.out;
      EXPECT_NE(r.out.find("FAILED"), std::string::npos) << r.out;
      if (!message.empty()) {
        EXPECT_NE(r.out.find(message), std::string::npos) << file << ":\n" << r.out;
      }
      EXPECT_NE(r.err.find("does not verify"), std::string::npos) << r.err;
    }
  }
}

TEST_F(Evidence, AnEnvelopeOfTheWrongShapeFailsCleanly) {
  // Hand-written envelopes whose fields have the wrong JSON types: refused with a reason, exit 1.
  const std::string payload = nlohmann::json::parse(slurp(package + "/statement.dsse.json"))["payload"];
  const std::vector<std::string> envelopes = {
      "[]",
      R"({"payloadType": 7})",
      R"({"payloadType": "application/vnd.in-toto+json", "payload": ")" + payload + R"(", "signatures": "x"})",
      R"({"payloadType": "application/vnd.in-toto+json", "payload": ")" + payload + R"(", "signatures": [1, {"sig": 2, "keyid": []}]})"};
  for (const auto& envelope : envelopes) {
    const std::string dir = copy_package("shape");
    std::ofstream(dir + "/statement.dsse.json", std::ios::binary | std::ios::trunc) << envelope;
    const auto r = meshmark(*s, {"verify", dir, "--pubkey", *s / "pub.txt"});
    EXPECT_EQ(r.code, 1) << envelope << "\n" << r.out << r.err;
    EXPECT_NE(r.out.find("statement.dsse.json"), std::string::npos) << envelope << "\n" << r.out;
    EXPECT_NE(r.err.find("does not verify"), std::string::npos) << envelope << "\n" << r.err;
  }
}

TEST_F(Evidence, AddedFilesOtherKeysAndAlteredReferencedFilesFail) {
  std::string dir = copy_package("extra");
  std::ofstream(dir + "/note.txt") << "added later";
  auto r = meshmark(*s, {"verify", dir, "--pubkey", *s / "pub.txt"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("note.txt: in the package but not in the signed statement"), std::string::npos) << r.out;

  // Another installation's key is not trusted; no key at all is refused.
  Scratch other;
  ASSERT_EQ(meshmark(other, {"init", "--home", other / "home"}).code, 0);
  const auto pub = meshmark(other, {"evidence", "pubkey", "--home", other / "home"});
  std::ofstream(other / "pub.txt") << pub.out;
  r = meshmark(*s, {"verify", package, "--pubkey", other / "pub.txt"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("signature not valid for any trusted key"), std::string::npos) << r.out;
  r = meshmark(*s, {"verify", package});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("no trusted public key"), std::string::npos) << r.out;

  // A suspect file given that is not the one examined matches no subject; the issued copy altered
  // at its recorded place fails by name.
  const std::string original = slurp(copy_off);
  std::string altered = original;
  altered[altered.size() / 2] = altered[altered.size() / 2] == '1' ? '2' : '1';
  std::ofstream(copy_off, std::ios::binary | std::ios::trunc) << altered;
  r = meshmark(*s, {"verify", package, "--pubkey", *s / "pub.txt"});
  std::ofstream(copy_off, std::ios::binary | std::ios::trunc) << original;
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("FAILED  issued-copy/"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("differs from the SHA-256 recorded"), std::string::npos) << r.out;
}

TEST_F(Evidence, ReproduceRecomputesTheDetectionBitForBitAndNamesAnyDifference) {
  auto r = meshmark(*s, {"reproduce", std::to_string(detection), "--home", home});
  EXPECT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("identical: all"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("verdict          attributed (recorded attributed)"), std::string::npos) << r.out;
  // A record altered behind the store's back no longer reproduces, and the field is named.
  const std::string db = home + "/meshmark.db";
  ASSERT_EQ(std::system(("sqlite3 " + quote(db) + " \"UPDATE detections SET p_value = p_value * 2 WHERE id = " +
                         std::to_string(detection) + "\"").c_str()), 0);
  r = meshmark(*s, {"reproduce", std::to_string(detection), "--home", home});
  ASSERT_EQ(std::system(("sqlite3 " + quote(db) + " \"UPDATE detections SET p_value = p_value / 2 WHERE id = " +
                         std::to_string(detection) + "\"").c_str()), 0);
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("DIFFERS  /p_value"), std::string::npos) << r.out;
  // Each copy's score states the strength the copy was issued with; a record from before that
  // field still reproduces.
  r = meshmark(*s, {"detections", "--home", home, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const json dets = json::parse(r.out);
  r = meshmark(*s, {"copies", "--home", home, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  std::map<std::int64_t, double> issued;
  for (const auto& c : json::parse(r.out)) issued[c["id"].get<std::int64_t>()] = c["params"]["strength"].get<double>();
  int stated = 0;
  for (const auto& d : dets)
    if (d["id"].get<std::int64_t>() == detection)
      for (const auto& c : d["details"]["candidates"])
        for (const auto& cs : c["copies"]) {
          ASSERT_TRUE(cs.contains("strength")) << cs.dump();
          EXPECT_EQ(cs["strength"].get<double>(), issued.at(cs["copy_id"].get<std::int64_t>()));
          ++stated;
        }
  EXPECT_GT(stated, 0);
  ASSERT_EQ(std::system(("sqlite3 " + quote(db) + " \"UPDATE detections SET details_json = json_remove(details_json, " +
                         "'$.candidates[0].copies[0].strength') WHERE id = " + std::to_string(detection) + "\"").c_str()), 0);
  r = meshmark(*s, {"detections", "--home", home, "--json"});
  for (const auto& d : json::parse(r.out))
    if (d["id"].get<std::int64_t>() == detection) {
      EXPECT_FALSE(d["details"]["candidates"][0]["copies"][0].contains("strength"));
    }
  r = meshmark(*s, {"reproduce", std::to_string(detection), "--home", home});
  EXPECT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("identical: all"), std::string::npos) << r.out;
  r = meshmark(*s, {"reproduce", "999", "--home", home});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("no detection 999"), std::string::npos) << r.err;
}

TEST_F(Evidence, TheDaemonWritesAPackageForEveryAttributedDetection) {
  const fs::path dir = s->dir / "out/evidence";
  ASSERT_TRUE(fs::exists(dir));
  std::vector<fs::path> packages(fs::directory_iterator(dir), fs::directory_iterator{});
  ASSERT_EQ(packages.size(), 1u);
  EXPECT_EQ(packages[0].filename().string().rfind("MM-" + std::to_string(detection) + "-", 0), 0u);
  EXPECT_FALSE(fs::exists(packages[0] / "report.pdf")) << "evidence.pdf false";
  const auto r = meshmark(*s, {"verify", packages[0].string(), "--pubkey", *s / "pub.txt"});
  EXPECT_EQ(r.code, 0) << r.out;
  const auto jobs = json::parse(meshmark(*s, {"jobs", "list", "--home", home, "--json"}).out);
  int evidence_jobs = 0;
  for (const auto& j : jobs["jobs"])
    if (j["kind"] == "evidence") {
      ++evidence_jobs;
      EXPECT_EQ(j["state"], "completed");
    }
  EXPECT_EQ(evidence_jobs, 1) << "one package per attributed detection, none for the protect jobs";
}

// A local time-stamping authority (tests/cli/local_tsa.py: openssl ts behind a localhost HTTP
// server), stopped when the test ends.
struct LocalTsa {
  fs::path dir;
  pid_t pid = -1;
  explicit LocalTsa(const fs::path& d) : dir(d) {
    pid = ::fork();
    if (pid == 0) {
      ::execlp("python3", "python3", LOCAL_TSA_PY, dir.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    for (int i = 0; i < 300 && !fs::exists(dir / "port"); ++i) ::usleep(100000);
  }
  ~LocalTsa() {
    if (pid > 0) {
      ::kill(pid, SIGTERM);
      ::waitpid(pid, nullptr, 0);
    }
  }
  std::string url() const { return "http://127.0.0.1:" + slurp((dir / "port").string()); }
};

TEST_F(Evidence, TrustedTimestampFromAnRfc3161AuthorityVerifiesAndTamperingFails) {
  LocalTsa tsa(s->dir / "tsa");
  ASSERT_TRUE(fs::exists(tsa.dir / "port")) << "the local authority did not start";
  const std::string ca = (tsa.dir / "ca.pem").string(), dir = *s / "stamped";
  auto r = meshmark(*s, {"evidence", std::to_string(detection), dir, "--home", home, "--no-pdf", "--tsa-url",
                         tsa.url(), "--tsa-ca", ca});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(exists(dir + "/statement.tsr"));
  const json st = json::parse(slurp(dir + "/statement.json"));
  EXPECT_EQ(st["predicate"]["timestamp"]["requested"], true);
  r = meshmark(*s, {"verify", dir, "--pubkey", *s / "pub.txt", "--tsa-ca", ca});
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("ok      statement.tsr: RFC 3161 timestamp of statement.json verifies"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("(time "), std::string::npos) << r.out;
  // Without the authority's certificate the timestamp is reported as not checked.
  r = meshmark(*s, {"verify", dir, "--pubkey", *s / "pub.txt"});
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("skipped statement.tsr: present; its authority not checked"), std::string::npos) << r.out;
  // A flipped byte of the timestamp, or the timestamp removed, fails.
  std::string tsr = slurp(dir + "/statement.tsr");
  tsr[tsr.size() / 2] = static_cast<char>(tsr[tsr.size() / 2] ^ 0x01);
  std::ofstream(dir + "/statement.tsr", std::ios::binary | std::ios::trunc) << tsr;
  r = meshmark(*s, {"verify", dir, "--pubkey", *s / "pub.txt", "--tsa-ca", ca});
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("FAILED  statement.tsr: SHA-256 differs from the signed record"), std::string::npos) << r.out;
  fs::remove(dir + "/statement.tsr");
  r = meshmark(*s, {"verify", dir, "--pubkey", *s / "pub.txt"});
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("statement.tsr: the statement says a timestamp was requested, but it is missing"),
            std::string::npos) << r.out;
  // An authority that does not answer fails the package and leaves nothing behind.
  r = meshmark(*s, {"evidence", std::to_string(detection), *s / "unstamped", "--home", home, "--no-pdf",
                    "--tsa-url", "http://127.0.0.1:1/"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("did not answer"), std::string::npos) << r.err;
  EXPECT_FALSE(exists(*s / "unstamped"));
}

TEST_F(Evidence, PackagesSignedBeforeAKeyRotationStillVerify) {
  const auto before = meshmark(*s, {"evidence", "pubkey", "--home", home}).out;
  auto r = meshmark(*s, {"evidence", "rotate-key", "--home", home});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto after = meshmark(*s, {"evidence", "pubkey", "--home", home}).out;
  EXPECT_NE(before, after);
  const std::string dir = *s / "after-rotation";
  ASSERT_EQ(meshmark(*s, {"evidence", std::to_string(detection), dir, "--home", home, "--no-pdf"}).code, 0);
  // The home trusts both keys; each exported key verifies only its own packages.
  EXPECT_EQ(meshmark(*s, {"verify", package, "--home", home}).code, 0);
  EXPECT_EQ(meshmark(*s, {"verify", dir, "--home", home}).code, 0);
  EXPECT_EQ(meshmark(*s, {"verify", package, "--pubkey", *s / "pub.txt"}).code, 0);
  EXPECT_EQ(meshmark(*s, {"verify", dir, "--pubkey", *s / "pub.txt"}).code, 1);
  ASSERT_EQ(std::system(("sqlite3 " + quote(home + "/meshmark.db") +
                         " \"SELECT count(*) FROM audit_log WHERE action = 'evidence.key.rotate'\" >" +
                         quote(*s / "rotations.txt")).c_str()), 0);
  EXPECT_EQ(slurp(*s / "rotations.txt"), "1\n") << "the rotation is in the audit log";
}

TEST_F(Evidence, RefusalsNameTheReason) {
  auto r = meshmark(*s, {"evidence", "999", *s / "p999", "--home", home});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("no detection 999"), std::string::npos) << r.err;
  EXPECT_FALSE(exists(*s / "p999"));
  r = meshmark(*s, {"evidence", std::to_string(detection), package, "--home", home});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("exists and is not an empty folder"), std::string::npos) << r.err;
  r = meshmark(*s, {"evidence", "abc", *s / "x", "--home", home});
  EXPECT_EQ(r.code, 64) << r.err;
  // Nothing half-written beside the package.
  for (const auto& e : fs::directory_iterator(s->dir))
    EXPECT_EQ(e.path().filename().string().find(".partial-"), std::string::npos) << e.path();
}

TEST_F(Evidence, NoSecretReachesThePackage) {
  const std::string master = slurp(home + "/master.key"), signing = slurp(home + "/signing.key");
  auto trim = [](std::string k) { return k.substr(0, k.find_first_of("\r\n")); };
  ASSERT_EQ(trim(master).size(), 64u);
  ASSERT_EQ(trim(signing).size(), 64u);
  for (const auto& e : fs::directory_iterator(package)) {
    const std::string bytes = slurp(e.path().string());
    EXPECT_EQ(bytes.find(trim(master)), std::string::npos) << e.path();
    EXPECT_EQ(bytes.find(trim(signing)), std::string::npos) << e.path();
  }
}

// Decoded PNG: the share of pixels that are not (near) white.
double inked_share(const std::string& path) {
  png_image img{};
  img.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&img, path.c_str())) return -1;
  img.format = PNG_FORMAT_RGB;
  std::vector<unsigned char> px(PNG_IMAGE_SIZE(img));
  if (!png_image_finish_read(&img, nullptr, px.data(), 0, nullptr)) return -1;
  std::size_t inked = 0, n = px.size() / 3;
  for (std::size_t i = 0; i < n; ++i)
    if (px[3 * i] < 235 || px[3 * i + 1] < 235 || px[3 * i + 2] < 235) ++inked;
  return static_cast<double>(inked) / static_cast<double>(n);
}

TEST_F(Evidence, ReportRendersInHeadlessChromiumAndPrintsToPdf) {
  if (!chromium_installed()) {
    if (under_ci()) FAIL() << "chromium is not installed (scripts/install-deps.sh installs it)";
    GTEST_SKIP() << "chromium is not installed: the browser check did not run";
  }
  EXPECT_TRUE(exists(package + "/report.pdf"));
  EXPECT_EQ(slurp(package + "/report.pdf").rfind("%PDF-", 0), 0u);
  const std::string flags =
      " --headless --no-sandbox --disable-gpu --no-first-run --disable-background-networking"
      " --disable-component-update --disable-sync --user-data-dir=" + quote(*s / "profile");
  const std::string page = "file://" + package + "/report.html";
  const std::string dom = *s / "dom.html", shot = *s / "shot.png";
  ASSERT_EQ(std::system(("timeout 120 chromium" + flags + " --dump-dom " + quote(page) + " >" + quote(dom) +
                         " 2>/dev/null").c_str()), 0);
  const std::string d = slurp(dom);
  EXPECT_NE(d.find("Verdict: the suspect file"), std::string::npos);
  EXPECT_NE(d.find("data-pictures-decoded=\"4\""), std::string::npos)
      << "every embedded picture decoded by the browser (side by side, distance, null, copies)";
  ASSERT_EQ(std::system(("timeout 120 chromium" + flags + " --window-size=1100,1400 --screenshot=" + quote(shot) +
                         " " + quote(page) + " >/dev/null 2>&1").c_str()), 0);
  const double ink = inked_share(shot);
  EXPECT_GT(ink, 0.05) << "the screenshot is blank";
  EXPECT_LT(ink, 0.95);
}

}  // namespace
