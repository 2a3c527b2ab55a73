// Webhooks: Standard Webhooks signatures, one delivery job per endpoint per final state (never
// doubled, none for deliveries themselves), and deliveries to a real HTTP receiver: 2xx
// completes, anything else is retried, an endpoint no longer configured fails for good.
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <mutex>
#include <set>
#include <nlohmann/json.hpp>

#include "http/server.h"
#include "service/webhooks.h"
#include "store/store.h"

namespace {

namespace fs = std::filesystem;
using namespace mm;
using nlohmann::json;

// The Standard Webhooks specification's example (secret, id, timestamp, body -> signature).
TEST(Webhooks, SignsAsTheSpecificationsExample) {
  const fs::path f = fs::temp_directory_path() / ("mm-whsec-" + std::to_string(::getpid()));
  std::ofstream(f) << "# pdm\nwhsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw\n";
  ::chmod(f.c_str(), 0600);
  const auto secrets = service::read_webhook_secrets(f.string());
  EXPECT_EQ(service::webhook_signature(secrets, "msg_p5jXN8AQM9LWM0D4loKWxJek", "1614265330", "{\"test\": 2432232314}"),
            "v1,g0hM9SsE+OTPJTGt/tmIKtSyZlE3uFJELVlNIOLJ1OE=");
  ::chmod(f.c_str(), 0644);
  EXPECT_THROW(service::read_webhook_secrets(f.string()), service::PermanentError) << "others can read it";
  ::chmod(f.c_str(), 0600);
  std::ofstream(f) << "whsec_notbase64!\n";
  EXPECT_THROW(service::read_webhook_secrets(f.string()), service::PermanentError);
  fs::remove(f);
  const std::string fresh = service::new_webhook_secret();
  EXPECT_EQ(fresh.rfind("whsec_", 0), 0u);
  EXPECT_NE(fresh, service::new_webhook_secret());
}

struct WebhookTest : ::testing::Test {
  fs::path dir;
  std::unique_ptr<store::Store> st;
  service::Config cfg;
  std::unique_ptr<http::Server> receiver;
  std::mutex m;
  std::vector<http::Request> received;
  int answer = 204;

  void SetUp() override {
    dir = fs::temp_directory_path() / ("mm-hooks-" + std::to_string(::getpid()) + "-" +
                                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir);
    fs::create_directories(dir);
    store::StoreOptions o;
    o.db_path = (dir / "m.db").string();
    st = store::open_sqlite_store(o);
    http::Routes routes;
    routes.upload_dir = dir.string();
    routes.handle = [this](http::Request& r) {
      std::lock_guard<std::mutex> l(m);
      received.push_back(r);
      http::Response res;
      res.status = answer;
      return res;
    };
    receiver = std::make_unique<http::Server>(http::parse_listen("127.0.0.1:0"), http::Limits{}, routes);
    receiver->start();
    std::ofstream(dir / "pdm.secret") << "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw\n";
    ::chmod((dir / "pdm.secret").c_str(), 0600);
    cfg.webhooks = {{"pdm", "http://127.0.0.1:" + std::to_string(receiver->port()) + "/hooks", (dir / "pdm.secret").string()},
                    {"audit", "http://127.0.0.1:" + std::to_string(receiver->port()) + "/audit", (dir / "pdm.secret").string()}};
  }
  void TearDown() override {
    receiver.reset();
    st.reset();
    fs::remove_all(dir);
  }
  std::int64_t finish_a_job(const std::string& kind, const std::string& key) {
    store::JobSpec spec;
    spec.kind = kind;
    spec.idempotency_key = key;
    const auto id = st->enqueue(spec).job.id;
    const auto j = st->claim("w", 60000, {kind});
    EXPECT_EQ(j->id, id);
    st->complete(id, "w", store::JobRecords{});
    return id;
  }
  std::vector<store::Job> deliveries() {
    store::JobFilter f;
    f.kind = "webhook";
    return st->list_jobs(f);
  }
};

TEST_F(WebhookTest, OneDeliveryPerEndpointPerFinalStateNeverTwice) {
  EXPECT_EQ(service::dispatch_webhooks(*st, cfg), 0);  // a new consumer starts after the newest event
  const auto done = finish_a_job("detect", "a");
  store::JobSpec spec;
  spec.kind = "protect";
  const auto cancelled = st->enqueue(spec).job.id;
  st->cancel(cancelled);
  EXPECT_EQ(service::dispatch_webhooks(*st, cfg), 2);
  EXPECT_EQ(service::dispatch_webhooks(*st, cfg), 0);
  const auto jobs = deliveries();
  ASSERT_EQ(jobs.size(), 4u);
  std::set<std::string> seen;
  for (const auto& j : jobs) {
    const json p = json::parse(j.payload_json);
    seen.insert(p["endpoint"].get<std::string>() + ":" + std::to_string(p["job_id"].get<std::int64_t>()) + ":" +
                p["state"].get<std::string>());
  }
  EXPECT_EQ(seen, (std::set<std::string>{"pdm:" + std::to_string(done) + ":succeeded", "audit:" + std::to_string(done) + ":succeeded",
                                         "pdm:" + std::to_string(cancelled) + ":cancelled",
                                         "audit:" + std::to_string(cancelled) + ":cancelled"}));
  // A delivery reaching its own final state raises no event.
  const auto d = st->claim("w", 60000, {"webhook"});
  st->complete(d->id, "w", store::JobRecords{});
  EXPECT_EQ(service::dispatch_webhooks(*st, cfg), 0);
}

TEST_F(WebhookTest, DeliversASignedThinNotificationAndRetriesFailures) {
  service::dispatch_webhooks(*st, cfg);
  const auto done = finish_a_job("detect", "b");
  ASSERT_EQ(service::dispatch_webhooks(*st, cfg), 1);
  service::HandlerContext ctx{cfg, "w1"};
  store::Job delivery;
  for (const auto& j : deliveries())
    if (json::parse(j.payload_json)["endpoint"] == "pdm") delivery = j;
  const auto rec = service::run_webhook(*st, delivery, ctx);
  ASSERT_EQ(received.size(), 1u);
  const http::Request r = received[0];  // a copy: the vector grows below
  EXPECT_EQ(r.method, "POST");
  EXPECT_EQ(r.path, "/hooks");
  const json body = json::parse(r.body);
  EXPECT_EQ(body["type"], "job.succeeded");
  EXPECT_EQ(body["data"]["job_id"], done);
  EXPECT_EQ(body["data"]["links"]["self"], "/v1/jobs/" + std::to_string(done));
  EXPECT_FALSE(body["data"].contains("payload"));
  const auto secrets = service::read_webhook_secrets((dir / "pdm.secret").string());
  EXPECT_EQ(r.header("webhook-signature"),
            service::webhook_signature(secrets, r.header("webhook-id"), r.header("webhook-timestamp"), r.body));
  EXPECT_EQ(r.header("webhook-id").rfind("msg_", 0), 0u);
  EXPECT_EQ(json::parse(rec.result_json)["status"], 204);

  answer = 500;
  try {
    service::run_webhook(*st, delivery, ctx);
    FAIL() << "a 500 answer must fail the attempt";
  } catch (const service::PermanentError&) {
    FAIL() << "a 500 answer is retried, not final";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("HTTP 500"), std::string::npos) << e.what();
  }
  EXPECT_EQ(received.size(), 2u);
  EXPECT_EQ(received[1].header("webhook-id"), r.header("webhook-id")) << "a retry is the same message";

  service::Config gone = cfg;
  gone.webhooks.clear();
  service::HandlerContext gone_ctx{gone, "w1"};
  EXPECT_THROW(service::run_webhook(*st, delivery, gone_ctx), service::PermanentError);
  receiver->stop();
  answer = 204;
  EXPECT_THROW(service::run_webhook(*st, delivery, ctx), std::runtime_error) << "no answer is retried too";
}

}  // namespace
