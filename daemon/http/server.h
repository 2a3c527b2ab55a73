// A small HTTP/1.1 server for meshmarkd's API: Boost.Beast's parser over plain sockets, every
// receive bounded in bytes and time.
//
// Why Beast and not Debian's cpp-httplib 0.11.4: that library is compiled with flaws fixed only in
// later releases (unbounded chunked bodies, no header-count limit, gzip bodies inflated without a
// cap, Transfer-Encoding accepted beside Content-Length), and none of them can be switched off from
// outside. Beast is header-only in Debian's Boost 1.74 and leaves the I/O to us: its parser refuses
// Transfer-Encoding with Content-Length, caps header and body bytes (chunked ones too), and never
// decodes a body, and our own loop caps header count, time per read, open connections and
// threads. The server still listens on loopback or a Unix socket; TLS and client certificates are
// nginx's (config/nginx-meshmark.conf).
//
// Threads: one accepts and watches kept-alive connections between requests (so an idle client
// holds no thread); `threads` serve requests. At most threads + `queue` connections are open; one
// beyond that is answered 503 at once.
#pragma once
#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace mm::http {

struct Limits {
  std::size_t max_header_bytes = 16 * 1024;       // request line and headers together
  int max_headers = 64;                            // header fields
  std::size_t max_body_bytes = 1 << 20;            // bodies read into memory (JSON)
  std::uint64_t max_upload_bytes = 256ull << 20;   // bodies streamed to a file (uploads)
  int read_timeout_ms = 30000;                     // one receive, mid-request
  int idle_timeout_ms = 15000;                     // a kept-alive connection between requests
  int max_requests_per_connection = 1000;
  int threads = 4;
  int queue = 508;  // open connections beyond the serving threads (waiting or kept alive)
};

// A header's name lower-cased -> its value (repeated fields joined with ", ").
using Headers = std::map<std::string, std::string>;

struct Request {
  std::string method;  // "GET", "POST", ...
  std::string target;  // as sent: path and query
  std::string path;    // percent-decoded path
  std::map<std::string, std::string> query;  // percent-decoded
  Headers headers;
  std::string body;    // in-memory bodies
  // Streamed bodies (Routes::streams_body): a file in Routes::upload_dir, its size and SHA-256.
  // The file is removed after the handler returns unless the handler moved it away.
  std::string body_file;
  std::uint64_t body_size = 0;
  std::string body_sha256;
  std::string peer;  // "127.0.0.1:53122" or "unix"

  std::string header(const std::string& lower_name) const;
};

struct Response {
  int status = 200;
  std::string content_type = "application/json";
  std::string body;
  std::vector<std::pair<std::string, std::string>> headers;
  std::string file;  // when set, the body is this file's bytes, streamed (body ignored)
  bool remove_file = false;  // the file is a temporary one: removed once sent (or not)
};

// RFC 9457 problem details: {"type", "title", "status", "detail"} plus `extra`'s members.
Response problem(int status, const std::string& title, const std::string& detail,
                 const std::string& extra_json_object = "{}");

struct Routes {
  // Whether this request's body is streamed to a file (decided on its head: method, path, query,
  // headers); otherwise it is read into memory up to Limits::max_body_bytes.
  std::function<bool(const Request&)> streams_body = [](const Request&) { return false; };
  std::string upload_dir;  // where streamed bodies are written (must exist)
  std::function<Response(Request&)> handle;
};

// "127.0.0.1:8440", "[::1]:8440", "localhost:0" (0: any free port) or "unix:/run/meshmark/api.sock".
struct ListenAddress {
  bool unix_socket = false;
  std::string host;  // or the socket's path
  int port = 0;
};
ListenAddress parse_listen(const std::string& text);  // std::invalid_argument naming the reason

class Server {
 public:
  Server(ListenAddress where, Limits limits, Routes routes);
  ~Server();  // stops
  void start();           // binds and listens (std::runtime_error naming the address), then serves
  void stop();            // closes the listener, finishes requests in progress, joins the threads
  int port() const;       // the bound TCP port (after start)
  std::string address() const;  // where it listens, for logs

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mm::http
