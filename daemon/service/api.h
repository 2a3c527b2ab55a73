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
#include <optional>
#include <set>
#include <string>
#include <vector>

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

  using Response = http::Response;
  struct Caller {  // the token a request came with
    std::string name;
    store::TokenRole role = store::TokenRole::read;
    bool allows(store::TokenRole needed) const { return static_cast<int>(role) >= static_cast<int>(needed); }
  };
  using Params = std::vector<std::string>;
  struct Route {
    const char* method;                     // a GET route answers HEAD too
    const char* path;                       // "/v1/jobs/{id}": {name} matches one segment
    std::optional<store::TokenRole> role;   // none: no token needed
    Response (*fn)(Api&, http::Request&, const Caller&, const Params&);
  };
  // Every route the API serves, as docs/openapi.json documents them.
  static const std::vector<Route>& route_table();

 private:
  Response ready();
  Response queue();
  Response metrics();
  Response upload_part(http::Request& req);
  Response part(const std::string& sha256);
  Response submit(http::Request& req, const Caller& who, const std::string& kind);
  Response job(const std::string& id);
  Response jobs(const http::Request& req);
  Response job_action(const std::string& id, const std::string& action, const Caller& who);
  Response job_file(const std::string& id, const std::string& which, const http::Request& req);
  Response detection_of(const std::string& id);
  Response evidence(const std::string& id, const http::Request& req);
  Response request_evidence(const std::string& id, const Caller& who);

  store::Store& st_;
  std::function<std::shared_ptr<const Config>()> config_;
  std::mutex inflight_m_;
  std::set<std::string> inflight_;  // idempotency keys whose first request is being handled
};

// The API's state names: queued, running, retrying, succeeded, failed, cancelled.
const char* api_state(store::JobState s);

}  // namespace mm::service
