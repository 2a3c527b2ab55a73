// meshmarkd's HTTP API, version 1 (docs/api.md; docs/openapi.json describes every route): what a
// PDM system calls to upload parts, submit protect and detect jobs, follow them and fetch what
// they produced. Routes over the store; the transport is http::Server.
//
// Every /v1 route needs `Authorization: Bearer <token>` (meshmark token create) of a role that
// allows it; errors are RFC 9457 problem details naming the field and the reason. Submissions
// take an Idempotency-Key (IETF draft-ietf-httpapi-idempotency-key-header): the same key and body
// return the same jobs, the same key with another body is refused (422), a key whose first
// request is still being handled is refused (409). Keys live as long as their jobs.
#pragma once
#include <functional>
#include <memory>
#include <mutex>
#include <set>
#include <string>

#include "http/server.h"
#include "service/config.h"
#include "store/store.h"

namespace mm::service {

class Api {
 public:
  // st: the API's own store connection (calls are serialized on it). config: read per request,
  // so a reload applies to the next one.
  Api(store::Store& st, std::function<std::shared_ptr<const Config>()> config);
  http::Routes routes(const std::string& upload_dir);
  http::Response handle(http::Request& req);

 private:
  struct Caller;
  http::Response route(http::Request& req, const Caller& who);
  http::Response upload_part(http::Request& req);
  http::Response submit(http::Request& req, const Caller& who, const std::string& kind);
  http::Response job(std::int64_t id);
  http::Response jobs(const http::Request& req);
  http::Response job_action(std::int64_t id, const std::string& action, const Caller& who);
  http::Response job_file(std::int64_t id, const std::string& which, const http::Request& req);
  http::Response detection_of(std::int64_t id);

  store::Store& st_;
  std::function<std::shared_ptr<const Config>()> config_;
  std::mutex inflight_m_;
  std::set<std::string> inflight_;  // idempotency keys whose first request is being handled
};

// The API's state names: queued, running, retrying, succeeded, failed, cancelled.
const char* api_state(store::JobState s);

}  // namespace mm::service
