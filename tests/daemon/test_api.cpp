// meshmarkd's HTTP API over a real store and server: tokens and roles, uploads, submissions with
// Idempotency-Key semantics, job status, lists, cancel and retry, problem details.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "http/server.h"
#include "service/api.h"
#include "service/handlers.h"
#include "store/store.h"

namespace {

namespace fs = std::filesystem;
using namespace mm;
using nlohmann::json;

struct Reply {
  int status = 0;
  std::string head, body;
  json j;
  std::string header(const std::string& name) const {
    const auto at = head.find("\r\n" + name + ": ");
    if (at == std::string::npos) return "";
    const auto start = at + name.size() + 4;
    return head.substr(start, head.find("\r\n", start) - start);
  }
};

Reply call(int port, const std::string& method, const std::string& target, const std::string& token,
           const std::string& body = "", const std::string& extra_headers = "") {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in sa{};
  sa.sin_family = AF_INET;
  sa.sin_port = htons(static_cast<uint16_t>(port));
  sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&sa), sizeof sa) != 0) return {};
  std::string req = method + " " + target + " HTTP/1.1\r\nHost: t\r\nConnection: close\r\n";
  if (!token.empty()) req += "Authorization: Bearer " + token + "\r\n";
  req += extra_headers;
  if (!body.empty() || method == "POST") req += "Content-Length: " + std::to_string(body.size()) + "\r\n";
  req += "\r\n" + body;
  ::send(fd, req.data(), req.size(), MSG_NOSIGNAL);
  std::string out;
  char buf[8192];
  for (;;) {
    struct pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 5000) <= 0) break;
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    out.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fd);
  Reply r;
  const auto split = out.find("\r\n\r\n");
  if (out.size() < 12 || split == std::string::npos) return r;
  r.status = std::stoi(out.substr(9, 3));
  r.head = out.substr(0, split + 2);
  r.body = out.substr(split + 4);
  r.j = json::parse(r.body, nullptr, false);
  return r;
}

struct ApiTest : ::testing::Test {
  fs::path dir;
  std::unique_ptr<store::Store> st;
  std::shared_ptr<service::Config> cfg = std::make_shared<service::Config>();
  std::unique_ptr<service::Api> api;
  std::unique_ptr<http::Server> server;
  std::string reader, submitter, admin;

  void SetUp() override {
    dir = fs::temp_directory_path() / ("mm-api-" + std::to_string(::getpid()) + "-" +
                                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir);
    fs::create_directories(dir / "uploads");
    fs::create_directories(dir / "in");
    store::StoreOptions o;
    o.db_path = (dir / "m.db").string();
    o.master_key = keys::SecretKey::random();
    st = store::open_sqlite_store(o);
    st->add_customer("alice");
    st->add_customer("bob");
    reader = st->create_token("dashboard", store::TokenRole::read).secret;
    submitter = st->create_token("pdm", store::TokenRole::submit).secret;
    admin = st->create_token("ops", store::TokenRole::admin).secret;
    cfg->home = dir.string();
    cfg->input_roots = {(dir / "in").string()};
    cfg->max_attempts = 3;
    api = std::make_unique<service::Api>(*st, [this] { return std::shared_ptr<const service::Config>(cfg); });
    http::Limits limits;
    limits.max_upload_bytes = 100000;
    server = std::make_unique<http::Server>(http::parse_listen("127.0.0.1:0"), limits, api->routes((dir / "uploads").string()));
    server->start();
  }
  void TearDown() override {
    server.reset();
    api.reset();
    st.reset();
    fs::remove_all(dir);
  }
  int port() const { return server->port(); }
  std::string upload(const std::string& bytes, const std::string& name = "part.stl") {
    const Reply r = call(port(), "POST", "/v1/parts?name=" + name, submitter, bytes);
    EXPECT_EQ(r.status, 201) << r.body;
    return r.j.value("sha256", "");
  }
};

TEST_F(ApiTest, HealthNeedsNoTokenAndEverythingElseDoes) {
  EXPECT_EQ(call(port(), "GET", "/healthz", "").status, 200);
  EXPECT_EQ(call(port(), "GET", "/readyz", "").status, 200);
  const Reply none = call(port(), "GET", "/v1/jobs", "");
  EXPECT_EQ(none.status, 401);
  EXPECT_EQ(none.header("WWW-Authenticate"), "Bearer realm=\"meshmark\"");
  EXPECT_EQ(none.header("Content-Type"), "application/problem+json");
  EXPECT_EQ(none.j["status"], 401);
  EXPECT_EQ(call(port(), "GET", "/v1/jobs", "mmt_" + std::string(64, '0')).status, 401);
  EXPECT_EQ(call(port(), "GET", "/v1/jobs", reader).status, 200);
}

TEST_F(ApiTest, ARevokedTokenIsRefused) {
  EXPECT_EQ(call(port(), "GET", "/v1/jobs", reader).status, 200);
  ASSERT_TRUE(st->revoke_token("dashboard"));
  EXPECT_EQ(call(port(), "GET", "/v1/jobs", reader).status, 401);
  EXPECT_FALSE(st->revoke_token("dashboard"));
}

TEST_F(ApiTest, RolesAreChecked) {
  const Reply r = call(port(), "POST", "/v1/parts?name=a.stl", reader, "solid x\nendsolid x\n");
  EXPECT_EQ(r.status, 403);
  EXPECT_NE(r.j.value("detail", "").find("needs submit"), std::string::npos) << r.body;
  const std::string sha = upload("solid a\nendsolid a\n");
  const Reply job = call(port(), "POST", "/v1/jobs/detect", submitter, json{{"part", {{"sha256", sha}, {"name", "a.stl"}}}}.dump());
  ASSERT_EQ(job.status, 202) << job.body;
  const std::string id = std::to_string(job.j["jobs"][0]["id"].get<int>());
  ASSERT_EQ(call(port(), "POST", "/v1/jobs/" + id + "/cancel", submitter).status, 200);
  EXPECT_EQ(call(port(), "POST", "/v1/jobs/" + id + "/retry", submitter).status, 403);
  EXPECT_EQ(call(port(), "POST", "/v1/jobs/" + id + "/retry", admin).j["state"], "queued");
}

TEST_F(ApiTest, UploadsArePutInTheBlobStoreByTheirHash) {
  const std::string bytes = "solid u\nendsolid u\n";
  const std::string sha = upload(bytes);
  ASSERT_EQ(sha.size(), 64u);
  EXPECT_TRUE(st->blobs().contains(sha));
  EXPECT_EQ(st->blobs().size(sha), bytes.size());
  EXPECT_EQ(call(port(), "GET", "/v1/parts/" + sha, reader).j["size"], bytes.size());
  EXPECT_EQ(call(port(), "GET", "/v1/parts/" + std::string(64, 'a'), reader).status, 404);
  const Reply big = call(port(), "POST", "/v1/parts?name=big.stl", submitter, std::string(100001, 'x'));
  EXPECT_EQ(big.status, 413);
  const Reply noname = call(port(), "POST", "/v1/parts", submitter, bytes);
  EXPECT_EQ(noname.status, 422);
  EXPECT_EQ(noname.j["field"], "name");
  EXPECT_EQ(call(port(), "POST", "/v1/parts?name=..%2Fescape.stl", submitter, bytes).j["field"], "name");
  EXPECT_TRUE(fs::is_empty(dir / "uploads")) << "no upload is left half-written";
}

TEST_F(ApiTest, ProtectMakesOneJobPerCustomerAndAnIdempotencyKeyReplaysThem) {
  const std::string sha = upload("solid p\nendsolid p\n");
  const std::string body = json{{"part", {{"sha256", sha}, {"name", "p.stl"}}}, {"customers", {"alice", "bob"}}}.dump();
  const std::string key = "Idempotency-Key: \"order-17\"\r\nContent-Type: application/json\r\n";
  const Reply first = call(port(), "POST", "/v1/jobs/protect", submitter, body, key);
  ASSERT_EQ(first.status, 202) << first.body;
  ASSERT_EQ(first.j["jobs"].size(), 2u);
  EXPECT_EQ(first.j["jobs"][0]["customer"], "alice");
  EXPECT_EQ(first.j["jobs"][1]["customer"], "bob");
  EXPECT_EQ(first.j["jobs"][0]["state"], "queued");
  EXPECT_EQ(first.header("Location"), "/v1/jobs/" + std::to_string(first.j["jobs"][0]["id"].get<int>()));
  EXPECT_FALSE(first.header("Retry-After").empty());
  EXPECT_EQ(first.j["jobs"][0]["created"], true);

  const Reply again = call(port(), "POST", "/v1/jobs/protect", submitter, body, key);
  ASSERT_EQ(again.status, 202);
  EXPECT_EQ(again.j["jobs"][0]["id"], first.j["jobs"][0]["id"]);
  EXPECT_EQ(again.j["jobs"][1]["id"], first.j["jobs"][1]["id"]);
  EXPECT_EQ(again.j["jobs"][0]["created"], false);
  EXPECT_EQ(again.header("Idempotent-Replayed"), "true");
  EXPECT_EQ(st->counts().available, 2);

  const std::string other = json{{"part", {{"sha256", sha}, {"name", "p.stl"}}}, {"customers", {"alice"}}, {"priority", 5}}.dump();
  const Reply misuse = call(port(), "POST", "/v1/jobs/protect", submitter, other, key);
  EXPECT_EQ(misuse.status, 422) << misuse.body;
  EXPECT_EQ(misuse.j["field"], "Idempotency-Key");
  EXPECT_EQ(st->counts().available, 2);

  // Another client's same key is its own.
  const Reply admins = call(port(), "POST", "/v1/jobs/protect", admin, body, key);
  EXPECT_EQ(admins.status, 202);
  EXPECT_NE(admins.j["jobs"][0]["id"], first.j["jobs"][0]["id"]);
}

TEST_F(ApiTest, ASubmissionWithoutAKeyFindsTheSameJobByWhatItIs) {
  const std::string sha = upload("solid q\nendsolid q\n");
  const std::string body = json{{"part", {{"sha256", sha}, {"name", "q.stl"}}}}.dump();
  const Reply a = call(port(), "POST", "/v1/jobs/detect", submitter, body);
  const Reply b = call(port(), "POST", "/v1/jobs/detect", submitter, body);
  ASSERT_EQ(a.status, 202);
  EXPECT_EQ(a.j["jobs"][0]["id"], b.j["jobs"][0]["id"]);
  EXPECT_EQ(st->counts().available, 1);
}

TEST_F(ApiTest, SubmissionsNameTheFieldThatIsWrong) {
  const std::string sha = upload("solid r\nendsolid r\n");
  const auto field_of = [&](const json& body, const std::string& kind = "protect") {
    const Reply r = call(port(), "POST", "/v1/jobs/" + kind, submitter, body.dump());
    EXPECT_EQ(r.header("Content-Type"), "application/problem+json") << r.body;
    return r.j.value("field", "(" + std::to_string(r.status) + ")");
  };
  const json part{{"sha256", sha}, {"name", "r.stl"}};
  EXPECT_EQ(field_of({{"customers", {"alice"}}}), "part");
  EXPECT_EQ(field_of({{"part", part}, {"customers", {"alice", "mallory"}}}), "customers[1]");
  EXPECT_EQ(field_of({{"part", part}, {"customers", json::array()}}), "customers");
  EXPECT_EQ(field_of({{"part", {{"sha256", std::string(64, 'b')}, {"name", "r.stl"}}}, {"customers", {"alice"}}}), "part.sha256");
  EXPECT_EQ(field_of({{"part", {{"sha256", sha}}}, {"customers", {"alice"}}}), "part.name");
  EXPECT_EQ(field_of({{"part", {{"sha256", sha}, {"name", "noext"}}}, {"customers", {"alice"}}}), "part.name");
  EXPECT_EQ(field_of({{"part", part}, {"customers", {"alice"}}, {"output_format", "exe"}}), "output_format");
  EXPECT_EQ(field_of({{"part", part}, {"customers", {"alice"}}, {"colour", "red"}}), "colour");
  EXPECT_EQ(field_of({{"part", part}, {"customers", {"alice"}}}, "detect"), "customers");
  EXPECT_EQ(field_of({{"part", {{"path", "/etc/passwd"}}}}, "detect"), "part.path");
  EXPECT_EQ(field_of({{"part", {{"path", (dir / "in" / ".." / "m.db").string()}}}}, "detect"), "part.path");
  const Reply notjson = call(port(), "POST", "/v1/jobs/detect", submitter, "{part", "Content-Type: application/json\r\n");
  EXPECT_EQ(notjson.status, 400);
  EXPECT_EQ(st->counts().available, 0) << "nothing was enqueued by a refused request";
}

TEST_F(ApiTest, APathUnderTheInputRootsIsStoredAtSubmission) {
  std::ofstream(dir / "in" / "s.stl") << "solid s\nendsolid s\n";
  const Reply r = call(port(), "POST", "/v1/jobs/detect", submitter, json{{"part", {{"path", (dir / "in" / "s.stl").string()}}}}.dump());
  ASSERT_EQ(r.status, 202) << r.body;
  EXPECT_EQ(r.j["jobs"][0]["name"], "s.stl");
  const auto job = st->get_job(r.j["jobs"][0]["id"].get<int>());
  const json p = json::parse(job->payload_json);
  EXPECT_TRUE(st->blobs().contains(p["input_sha256"].get<std::string>()));
}

TEST_F(ApiTest, JobsShowStateErrorsAndPageByCursor) {
  std::vector<int> ids;
  for (int k = 0; k < 5; ++k) {
    const std::string sha = upload("solid " + std::to_string(k) + "\nendsolid\n", "n" + std::to_string(k % 2) + ".stl");
    const Reply r = call(port(), "POST", "/v1/jobs/detect", submitter,
                         json{{"part", {{"sha256", sha}, {"name", "n" + std::to_string(k % 2) + ".stl"}}}}.dump());
    ids.push_back(r.j["jobs"][0]["id"].get<int>());
  }
  // A worker fails the oldest job for good: the API shows it failed, with its reason.
  const auto claimed = st->claim("w1", 60000);
  ASSERT_TRUE(claimed);
  st->fail(claimed->id, "w1", "n0.stl: not a mesh", false);
  const Reply failed = call(port(), "GET", "/v1/jobs/" + std::to_string(claimed->id), reader);
  EXPECT_EQ(failed.j["state"], "failed");
  EXPECT_EQ(failed.j["error"], "n0.stl: not a mesh");
  EXPECT_EQ(failed.j["attempts"], 1);

  const Reply page1 = call(port(), "GET", "/v1/jobs?limit=2", reader);
  ASSERT_EQ(page1.j["jobs"].size(), 2u);
  EXPECT_EQ(page1.j["jobs"][0]["id"], ids[4]);
  const std::string cursor = page1.j["next_cursor"].get<std::string>();
  const Reply page2 = call(port(), "GET", "/v1/jobs?limit=2&cursor=" + cursor, reader);
  EXPECT_EQ(page2.j["jobs"][0]["id"], ids[2]);
  const Reply page3 = call(port(), "GET", "/v1/jobs?limit=2&cursor=" + page2.j["next_cursor"].get<std::string>(), reader);
  EXPECT_EQ(page3.j["jobs"].size(), 1u);
  EXPECT_TRUE(page3.j["next_cursor"].is_null());

  EXPECT_EQ(call(port(), "GET", "/v1/jobs?state=failed", reader).j["jobs"].size(), 1u);
  EXPECT_EQ(call(port(), "GET", "/v1/jobs?state=queued&name=n1.stl", reader).j["jobs"].size(), 2u);
  EXPECT_EQ(call(port(), "GET", "/v1/jobs?state=done", reader).j["field"], "state");
  EXPECT_EQ(call(port(), "GET", "/v1/jobs/999999", reader).status, 404);
  EXPECT_EQ(call(port(), "GET", "/v1/jobs/abc", reader).status, 404);
  EXPECT_EQ(call(port(), "DELETE", "/v1/jobs/1", reader).status, 405);
  EXPECT_EQ(call(port(), "POST", "/v1/jobs/" + std::to_string(claimed->id) + "/cancel", submitter).status, 409);
  EXPECT_EQ(call(port(), "GET", "/v1/jobs/" + std::to_string(ids[0]) + "/copy", reader).status, 404)
      << "a detect job has no copy";
  EXPECT_EQ(call(port(), "GET", "/v1/jobs/" + std::to_string(ids[1]) + "/detection", reader).status, 409)
      << "a queued detection has no verdict yet";
}

TEST_F(ApiTest, TokensAreStoredHashedOnly) {
  const auto t = st->create_token("another", store::TokenRole::submit);
  EXPECT_EQ(t.secret.rfind("mmt_", 0), 0u);
  EXPECT_EQ(t.secret.size(), 68u);
  std::ifstream db(dir / "m.db", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(db)), {});
  EXPECT_EQ(bytes.find(t.secret.substr(4)), std::string::npos);
  EXPECT_THROW(st->create_token("another", store::TokenRole::read), store::StoreError);
  EXPECT_THROW(st->create_token("../x", store::TokenRole::read), store::StoreError);
  EXPECT_EQ(st->list_tokens().size(), 4u);
}

}  // namespace

namespace {

std::string media_type(const std::string& content_type) { return content_type.substr(0, content_type.find(';')); }

// docs/openapi.json documents exactly the routes the server has, and each documented operation,
// called as a client would, answers with a status and media type the document gives for it.
TEST_F(ApiTest, TheOpenApiDocumentIsTheRouteTableAndEachRouteAnswersAsDocumented) {
  std::ifstream in(std::string(MESHMARK_SOURCE_DIR) + "/docs/openapi.json");
  const json doc = json::parse(in);
  ASSERT_EQ(doc["openapi"], "3.1.0");
  std::set<std::string> documented, served;
  for (const auto& [path, ops] : doc["paths"].items())
    for (const auto& [method, op] : ops.items()) documented.insert(method + " " + path);
  for (const auto& r : service::Api::route_table()) {
    std::string m = r.method;
    for (char& c : m) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    served.insert(m + " " + r.path);
  }
  EXPECT_EQ(documented, served);

  // Objects every route can be asked about: a succeeded protect job with its files, a succeeded
  // detection, a queued job to cancel and a cancelled one to retry.
  const std::string sha = upload("solid o\nendsolid o\n", "o.stl");
  const auto enqueue = [&](const std::string& kind, const std::string& key) {
    store::JobSpec spec;
    spec.kind = kind;
    spec.payload_json = json{{"name", "o.stl"}, {"input_sha256", sha}, {"customer", "alice"}}.dump();
    spec.idempotency_key = key;
    return st->enqueue(spec).job.id;
  };
  const auto protect = enqueue("protect", "p");
  const auto detect = enqueue("detect", "d");
  std::ofstream(dir / "copy.stl") << "solid copy\nendsolid copy\n";
  std::ofstream(dir / "copy.mmc") << "MMC";
  store::JobRecords pr;
  pr.result_json = json{{"output", (dir / "copy.stl").string()}, {"output_sha256", std::string(64, 'c')},
                        {"stream", (dir / "copy.mmc").string()}, {"stream_sha256", std::string(64, 'd')}}.dump();
  ASSERT_EQ(st->claim("w", 60000, {"protect"})->id, protect);
  st->complete(protect, "w", pr);
  store::JobRecords dr;
  store::NewDetection d;
  d.suspect_sha256 = sha;
  d.suspect_name = "o.stl";
  d.verdict = "no watermark found";
  dr.detections.push_back(d);
  ASSERT_EQ(st->claim("w", 60000, {"detect"})->id, detect);
  st->complete(detect, "w", dr);
  // Its evidence package, as the evidence job writes it.
  cfg->output_dir = (dir / "out").string();
  const fs::path package = service::evidence_package_dir(*cfg, *st->detection_of_job(detect));
  fs::create_directories(package);
  std::ofstream(package / "statement.json") << "{}";
  std::ofstream(package / "statement.dsse.json") << "{}";
  const auto queued = enqueue("detect", "q");
  const auto cancelled = enqueue("detect", "c");
  st->cancel(cancelled);

  const auto id_for = [&](const std::string& method, const std::string& path) -> std::int64_t {
    if (path.find("/cancel") != std::string::npos) return queued;
    if (path.find("/retry") != std::string::npos) return cancelled;
    if (path.find("/detection") != std::string::npos || path.find("/evidence") != std::string::npos) return detect;
    (void)method;
    return protect;
  };
  for (const auto& [path, ops] : doc["paths"].items()) {
    for (const auto& [method, op] : ops.items()) {
      std::string target = path, body, headers;
      const auto id_at = target.find("{id}");
      if (id_at != std::string::npos) target.replace(id_at, 4, std::to_string(id_for(method, path)));
      const auto sha_at = target.find("{sha256}");
      if (sha_at != std::string::npos) target.replace(sha_at, 8, sha);
      if (path == "/v1/parts") {
        target += "?name=again.stl";
        body = "solid again\nendsolid again\n";
      } else if (path == "/v1/jobs/protect") {
        body = json{{"part", {{"sha256", sha}, {"name", "o.stl"}}}, {"customers", {"bob"}}}.dump();
        headers = "Content-Type: application/json\r\n";
      } else if (path == "/v1/jobs/detect") {
        body = json{{"part", {{"sha256", sha}, {"name", "other.stl"}}}}.dump();
        headers = "Content-Type: application/json\r\n";
      }
      std::string upper = method;
      for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
      const bool open = op.contains("security") && op["security"].empty();
      const Reply r = call(port(), upper, target, open ? "" : admin, body, headers);
      const std::string status = std::to_string(r.status);
      ASSERT_TRUE(op["responses"].contains(status)) << upper << " " << target << " answered " << status << ": " << r.body;
      json response = op["responses"][status];
      if (response.contains("$ref")) response = doc["components"]["responses"]["Problem"];
      if (response.contains("content"))
        EXPECT_TRUE(response["content"].contains(media_type(r.header("Content-Type"))))
            << upper << " " << target << ": " << r.header("Content-Type");
      EXPECT_LT(r.status, 300) << upper << " " << target << ": " << r.body;
      if (!open) {
        const Reply anon = call(port(), upper, target, "", body, headers);
        EXPECT_EQ(anon.status, 401) << upper << " " << target;
        EXPECT_TRUE(op["responses"].contains("401")) << upper << " " << path;
      }
    }
  }
}

TEST_F(ApiTest, TheEvidencePackageIsOneTarAndCanBeRequested) {
  const std::string sha = upload("solid e\nendsolid e\n");
  const Reply sub = call(port(), "POST", "/v1/jobs/detect", submitter, json{{"part", {{"sha256", sha}, {"name", "e.stl"}}}}.dump());
  const auto id = sub.j["jobs"][0]["id"].get<std::int64_t>();
  const std::string base = "/v1/jobs/" + std::to_string(id) + "/evidence";
  EXPECT_EQ(call(port(), "GET", base, reader).status, 409) << "no verdict yet";
  ASSERT_EQ(st->claim("w", 60000)->id, id);
  store::JobRecords rec;
  store::NewDetection d;
  d.suspect_sha256 = sha;
  d.suspect_name = "e.stl";
  d.verdict = "attributed";
  rec.detections.push_back(d);
  st->complete(id, "w", rec);
  const Reply none = call(port(), "GET", base, reader);
  EXPECT_EQ(none.status, 404);
  EXPECT_NE(none.j.value("detail", "").find("no evidence package yet"), std::string::npos);
  EXPECT_EQ(call(port(), "POST", base, reader).status, 403);
  const Reply asked = call(port(), "POST", base, submitter);
  ASSERT_EQ(asked.status, 202) << asked.body;
  EXPECT_EQ(asked.j["jobs"][0]["kind"], "evidence");
  EXPECT_EQ(call(port(), "POST", base, submitter).j["jobs"][0]["id"], asked.j["jobs"][0]["id"]) << "asked twice, one job";

  cfg->output_dir = (dir / "out").string();
  const fs::path package = service::evidence_package_dir(*cfg, *st->detection_of_job(id));
  fs::create_directories(package);
  std::ofstream(package / "statement.json") << "{\"case\": 1}";
  std::ofstream(package / "statement.dsse.json") << "{}";
  std::ofstream(package / "report.html") << "<html></html>";
  const Reply tar = call(port(), "GET", base, reader);
  ASSERT_EQ(tar.status, 200) << tar.body;
  EXPECT_EQ(tar.header("Content-Type"), "application/x-tar");
  const fs::path got = dir / "got.tar";
  std::ofstream(got, std::ios::binary) << tar.body;
  const std::string listing_file = (dir / "listing.txt").string();
  ASSERT_EQ(std::system(("tar -tf " + got.string() + " > " + listing_file).c_str()), 0);
  std::ifstream listing(listing_file);
  const std::string names((std::istreambuf_iterator<char>(listing)), {});
  EXPECT_NE(names.find(package.filename().string() + "/statement.dsse.json"), std::string::npos) << names;
  EXPECT_NE(names.find(package.filename().string() + "/report.html"), std::string::npos) << names;
  EXPECT_EQ(call(port(), "GET", base, reader).body, tar.body) << "the same package, the same bytes";
  EXPECT_EQ(call(port(), "GET", base, reader, "", "If-None-Match: " + tar.header("ETag") + "\r\n").status, 304);
}

TEST_F(ApiTest, MetricsCountJobsByStateAndPassPromtool) {
  const std::string sha = upload("solid m\nendsolid m\n");
  const Reply sub = call(port(), "POST", "/v1/jobs/detect", submitter, json{{"part", {{"sha256", sha}, {"name", "m.stl"}}}}.dump());
  const auto id = sub.j["jobs"][0]["id"].get<std::int64_t>();
  ASSERT_EQ(st->claim("w", 60000)->id, id);
  st->complete(id, "w", store::JobRecords{});
  const Reply m = call(port(), "GET", "/metrics", reader);
  ASSERT_EQ(m.status, 200);
  EXPECT_EQ(m.header("Content-Type"), "text/plain; version=0.0.4; charset=utf-8");
  EXPECT_NE(m.body.find("meshmark_jobs_total{kind=\"detect\",state=\"queued\"} 1\n"), std::string::npos) << m.body;
  EXPECT_NE(m.body.find("meshmark_jobs_total{kind=\"detect\",state=\"running\"} 1\n"), std::string::npos);
  EXPECT_NE(m.body.find("meshmark_jobs_total{kind=\"detect\",state=\"succeeded\"} 1\n"), std::string::npos);
  EXPECT_NE(m.body.find("meshmark_job_duration_seconds_count{kind=\"detect\"} 1\n"), std::string::npos);
  EXPECT_NE(m.body.find("meshmark_build_info{"), std::string::npos);
  EXPECT_EQ(m.body.find("alice"), std::string::npos) << "no customer names as labels";
  EXPECT_EQ(call(port(), "GET", "/metrics", "").status, 401);

  // Prometheus's own checker (Debian's prometheus package); required under CI.
  if (std::system("command -v promtool >/dev/null 2>&1") != 0) {
    if (const char* ci = std::getenv("CI"); ci && std::string(ci) == "true") FAIL() << "promtool is not installed";
    GTEST_SKIP() << "promtool is not installed (apt-get install prometheus)";
  }
  const fs::path file = dir / "metrics.txt";
  std::ofstream(file) << m.body;
  const std::string cmd = "promtool check metrics < " + file.string() + " > " + (dir / "promtool.log").string() + " 2>&1";
  const int rc = std::system(cmd.c_str());
  std::ifstream log(dir / "promtool.log");
  EXPECT_EQ(rc, 0) << std::string((std::istreambuf_iterator<char>(log)), {});
}

}  // namespace

namespace {

// The status page in headless Chromium (Debian's chromium): with an admin token given as
// /#token=..., the counts and a failure's reason are in the DOM, and a screenshot is taken.
TEST_F(ApiTest, TheStatusPageShowsCountsAndFailuresInChromium) {
  const std::string sha = upload("solid s\nendsolid s\n");
  call(port(), "POST", "/v1/jobs/detect", submitter, json{{"part", {{"sha256", sha}, {"name", "broken.stl"}}}}.dump());
  const auto j = st->claim("w", 60000);
  ASSERT_TRUE(j);
  st->fail(j->id, "w", "broken.stl: not a mesh (no facet)", false);
  const std::string sha2 = upload("solid t\nendsolid t\n");
  call(port(), "POST", "/v1/jobs/detect", submitter, json{{"part", {{"sha256", sha2}, {"name", "waiting.stl"}}}}.dump());

  const Reply page = call(port(), "GET", "/", "");
  ASSERT_EQ(page.status, 200);
  EXPECT_EQ(page.header("Content-Type"), "text/html; charset=utf-8");
  EXPECT_NE(page.header("Content-Security-Policy").find("frame-ancestors 'none'"), std::string::npos);
  EXPECT_EQ(page.header("Access-Control-Allow-Origin"), "") << "no cross-site reads";
  EXPECT_EQ(page.body.find("mmt_"), std::string::npos) << "the page holds no token and no data";

  std::string browser;
  for (const char* b : {"chromium", "chromium-browser"})
    if (std::system(("command -v " + std::string(b) + " >/dev/null 2>&1").c_str()) == 0) browser = b;
  if (browser.empty()) {
    if (const char* ci = std::getenv("CI"); ci && std::string(ci) == "true") FAIL() << "chromium is not installed";
    GTEST_SKIP() << "chromium is not installed";
  }
  const std::string url = "http://127.0.0.1:" + std::to_string(port()) + "/#token=" + admin;
  const std::string flags = " --headless --no-sandbox --disable-gpu --no-first-run --disable-background-networking "
                            "--user-data-dir=" + (dir / "profile").string() + " --virtual-time-budget=10000 ";
  const fs::path dom = dir / "dom.html", shot = dir / "status.png";
  ASSERT_EQ(std::system(("timeout 120 " + browser + flags + "--dump-dom '" + url + "' > " + dom.string() + " 2>/dev/null").c_str()), 0);
  std::ifstream in(dom);
  const std::string html((std::istreambuf_iterator<char>(in)), {});
  EXPECT_NE(html.find("broken.stl: not a mesh (no facet)"), std::string::npos) << html.substr(0, 3000);
  EXPECT_NE(html.find("id=\"count-failed\"><b>1</b>failed"), std::string::npos) << html.substr(0, 3000);
  EXPECT_NE(html.find("id=\"count-queued\"><b>1</b>queued"), std::string::npos);
  EXPECT_NE(html.find("token ops (admin)"), std::string::npos);
  EXPECT_NE(html.find(">retry</button>"), std::string::npos) << "an admin may retry the failed job";
  ASSERT_EQ(std::system(("timeout 120 " + browser + flags + "--window-size=1200,900 --screenshot=" + shot.string() + " '" + url +
                         "' >/dev/null 2>&1").c_str()),
            0);
  ASSERT_TRUE(fs::exists(shot));
  EXPECT_GT(fs::file_size(shot), 10000u);
  if (const char* keep = std::getenv("MESHMARK_KEEP_SCREENSHOT")) fs::copy_file(shot, keep, fs::copy_options::overwrite_existing);
}

}  // namespace
