// Webhooks: a notification to each configured endpoint when a job reaches a final state, signed as
// the Standard Webhooks specification says (webhook-id, webhook-timestamp, webhook-signature:
// "v1,<base64 HMAC-SHA256 of id.timestamp.body>", one per secret during a rotation). Deliveries are
// jobs of kind "webhook": retried with the queue's backoff, listed with the other jobs (their
// attempts and errors are the delivery log), and enqueued from the store's job events in the
// transaction that moves its cursor, so none is lost or doubled by a crash.
#pragma once
#include <string>
#include <vector>

#include "service/config.h"
#include "service/handlers.h"
#include "store/store.h"

namespace mm::service {

// Turns new job events into one delivery job per endpoint of cfg.webhooks (none configured: the
// events are passed over). Called from the daemon's main loop; returns the events consumed.
int dispatch_webhooks(store::Store& st, const Config& cfg);

// The "webhook" job: POSTs the event's thin JSON (type, timestamp, job id, kind, state, link; no
// payload, result or secret) to its endpoint with curl. A 2xx answer completes it; any other
// answer or a network error is retried; an endpoint no longer configured fails it for good.
store::JobRecords run_webhook(store::Store& st, const store::Job& job, const HandlerContext& ctx);

// A secret file's secrets, decoded: lines "whsec_<base64 of 24 to 64 bytes>", '#' comments.
// PermanentError naming the file and line; the file must not be readable by others.
std::vector<std::string> read_webhook_secrets(const std::string& path);

// The webhook-signature header for these secrets (space-separated "v1,<base64>").
std::string webhook_signature(const std::vector<std::string>& secrets, const std::string& id,
                              const std::string& timestamp, const std::string& body);

// A new secret for a secret file: "whsec_" and base64 of 32 random bytes.
std::string new_webhook_secret();

}  // namespace mm::service
