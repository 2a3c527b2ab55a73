#include "http/server.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sodium.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/http/empty_body.hpp>
#include <boost/beast/http/buffer_body.hpp>
#include <boost/beast/http/error.hpp>
#include <boost/beast/http/parser.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/status.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/asio/error.hpp>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>
#include <stdexcept>

namespace mm::http {
namespace {

namespace beast = boost::beast;
namespace bhttp = boost::beast::http;
namespace fs = std::filesystem;
using boost::system::error_code;

// A socket read as Beast's SyncReadStream: each receive waits at most timeout_ms.
class TimedSocket {
 public:
  TimedSocket(int fd, int timeout_ms) : fd_(fd), timeout_ms_(timeout_ms) {}
  void set_timeout(int ms) { timeout_ms_ = ms; }

  template <class Buffers>
  std::size_t read_some(const Buffers& buffers) {
    error_code ec;
    const std::size_t n = read_some(buffers, ec);
    if (ec) throw boost::system::system_error(ec);
    return n;
  }
  template <class Buffers>
  std::size_t read_some(const Buffers& buffers, error_code& ec) {
    ec = {};
    for (auto it = boost::asio::buffer_sequence_begin(buffers); it != boost::asio::buffer_sequence_end(buffers); ++it) {
      boost::asio::mutable_buffer b = *it;
      if (b.size() == 0) continue;
      struct pollfd p{fd_, POLLIN, 0};
      const int ready = ::poll(&p, 1, timeout_ms_);
      if (ready == 0) {
        ec = beast::error::timeout;
        return 0;
      }
      if (ready < 0) {
        ec = error_code(errno, boost::system::system_category());
        return 0;
      }
      const ssize_t n = ::recv(fd_, b.data(), b.size(), 0);
      if (n == 0) {
        ec = boost::asio::error::eof;
        return 0;
      }
      if (n < 0) {
        ec = error_code(errno, boost::system::system_category());
        return 0;
      }
      return static_cast<std::size_t>(n);
    }
    return 0;
  }

 private:
  int fd_;
  int timeout_ms_;
};

bool send_all(int fd, const char* data, std::size_t size, int timeout_ms) {
  while (size > 0) {
    struct pollfd p{fd, POLLOUT, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return false;
    const ssize_t n = ::send(fd, data, size, MSG_NOSIGNAL);
    if (n <= 0) return false;
    data += n;
    size -= static_cast<std::size_t>(n);
  }
  return true;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// Percent-decoding; false on a malformed escape or a decoded NUL.
bool percent_decode(std::string_view in, std::string* out, bool plus_is_space) {
  out->clear();
  for (std::size_t i = 0; i < in.size(); ++i) {
    char c = in[i];
    if (c == '%') {
      if (i + 2 >= in.size()) return false;
      const int hi = hex_value(in[i + 1]), lo = hex_value(in[i + 2]);
      if (hi < 0 || lo < 0) return false;
      c = static_cast<char>(hi * 16 + lo);
      i += 2;
    } else if (c == '+' && plus_is_space) {
      c = ' ';
    }
    if (c == '\0') return false;
    out->push_back(c);
  }
  return true;
}

// Splits the target into path and query; false when either is malformed.
bool split_target(const std::string& target, Request* r) {
  if (target.empty() || target[0] != '/') return false;
  const auto q = target.find('?');
  if (!percent_decode(std::string_view(target).substr(0, q), &r->path, false)) return false;
  if (q == std::string::npos) return true;
  std::string_view rest = std::string_view(target).substr(q + 1);
  while (!rest.empty()) {
    const auto amp = rest.find('&');
    const std::string_view pair = rest.substr(0, amp);
    rest = amp == std::string_view::npos ? std::string_view() : rest.substr(amp + 1);
    if (pair.empty()) continue;
    const auto eq = pair.find('=');
    std::string k, v;
    if (!percent_decode(pair.substr(0, eq), &k, true)) return false;
    if (eq != std::string_view::npos && !percent_decode(pair.substr(eq + 1), &v, true)) return false;
    r->query[k] = v;
  }
  return true;
}

std::string status_line(int status) {
  const auto reason = bhttp::obsolete_reason(static_cast<bhttp::status>(status));
  return "HTTP/1.1 " + std::to_string(status) + " " + std::string(reason.data(), reason.size()) + "\r\n";
}

// Writes the response; false when the peer went away. keep_alive false adds Connection: close.
bool write_response(int fd, const Response& r, bool keep_alive, bool head_only, int timeout_ms) {
  std::uint64_t length = r.body.size();
  std::FILE* f = nullptr;
  if (!r.file.empty()) {
    f = std::fopen(r.file.c_str(), "rb");
    if (!f) return write_response(fd, problem(500, "Internal Server Error", "the file to send could not be opened"),
                                  false, head_only, timeout_ms);
    std::error_code ec;
    length = fs::file_size(r.file, ec);
    if (ec) length = 0;
  }
  std::string head = status_line(r.status);
  if (!r.content_type.empty()) head += "Content-Type: " + r.content_type + "\r\n";
  head += "Content-Length: " + std::to_string(length) + "\r\n";
  for (const auto& [k, v] : r.headers) head += k + ": " + v + "\r\n";
  head += keep_alive ? "Connection: keep-alive\r\n\r\n" : "Connection: close\r\n\r\n";
  // An in-memory body goes out with its head in one send: two small sends would meet the
  // client's delayed ACK (Nagle), about 40 ms a request.
  if (!f && !head_only) head += r.body;
  bool ok = send_all(fd, head.data(), head.size(), timeout_ms);
  if (ok && !head_only) {
    if (f) {
      std::vector<char> chunk(1 << 16);
      std::uint64_t left = length;
      while (ok && left > 0) {
        const std::size_t n = std::fread(chunk.data(), 1, std::min<std::uint64_t>(chunk.size(), left), f);
        if (n == 0) {
          ok = false;  // the file shrank under us: the peer sees a short body and the closed connection
          break;
        }
        ok = send_all(fd, chunk.data(), n, timeout_ms);
        left -= n;
      }
    }
  }
  if (f) std::fclose(f);
  return ok;
}

class Sha256 {
 public:
  Sha256() { crypto_hash_sha256_init(&state_); }
  void update(const char* data, std::size_t n) {
    crypto_hash_sha256_update(&state_, reinterpret_cast<const unsigned char*>(data), n);
  }
  std::string hex() {
    unsigned char out[crypto_hash_sha256_BYTES];
    crypto_hash_sha256_final(&state_, out);
    char text[2 * crypto_hash_sha256_BYTES + 1];
    sodium_bin2hex(text, sizeof text, out, sizeof out);
    return text;
  }

 private:
  crypto_hash_sha256_state state_;
};

std::string temp_name(const std::string& dir) {
  unsigned char rnd[12];
  randombytes_buf(rnd, sizeof rnd);
  char text[2 * sizeof rnd + 1];
  sodium_bin2hex(text, sizeof text, rnd, sizeof rnd);
  return (fs::path(dir) / (std::string(".upload-") + text + ".part")).string();
}

}  // namespace

std::string Request::header(const std::string& lower_name) const {
  const auto it = headers.find(lower_name);
  return it == headers.end() ? std::string() : it->second;
}

Response problem(int status, const std::string& title, const std::string& detail, const std::string& extra_json_object) {
  nlohmann::json j = nlohmann::json::object();
  const nlohmann::json extra = nlohmann::json::parse(extra_json_object, nullptr, false);
  if (extra.is_object()) j = extra;
  j["type"] = "about:blank";
  j["title"] = title;
  j["status"] = status;
  j["detail"] = detail;
  Response r;
  r.status = status;
  r.content_type = "application/problem+json";
  r.body = j.dump();
  return r;
}

ListenAddress parse_listen(const std::string& text) {
  ListenAddress a;
  if (text.rfind("unix:", 0) == 0) {
    a.unix_socket = true;
    a.host = text.substr(5);
    if (a.host.empty() || a.host[0] != '/') throw std::invalid_argument("a Unix socket needs an absolute path (unix:/run/...)");
    if (a.host.size() >= sizeof(sockaddr_un{}.sun_path)) throw std::invalid_argument("the Unix socket path is too long");
    return a;
  }
  const auto colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0) throw std::invalid_argument("expected host:port or unix:/path");
  a.host = text.substr(0, colon);
  if (a.host.size() > 2 && a.host.front() == '[' && a.host.back() == ']') a.host = a.host.substr(1, a.host.size() - 2);
  const std::string port = text.substr(colon + 1);
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos)
    throw std::invalid_argument("the port is not a number");
  a.port = std::stoi(port);
  if (a.port > 65535) throw std::invalid_argument("the port is above 65535");
  return a;
}

// A client connection: served by one thread at a time, parked with the acceptor between requests.
struct Connection {
  // A request head and what follows it in one read fit; the parser's own limits come first.
  explicit Connection(int socket, std::size_t max_header_bytes) : fd(socket), buf(max_header_bytes + 4096) {}
  int fd;
  std::string peer = "unix";
  beast::flat_buffer buf;
  int served = 0;  // requests answered
  std::chrono::steady_clock::time_point idle_since;
  ~Connection() {
    if (fd >= 0) ::close(fd);
  }
};
using ConnectionPtr = std::unique_ptr<Connection>;

struct Server::Impl {
  ListenAddress where;
  Limits limits;
  Routes routes;
  int listen_fd = -1;
  int wake_fd = -1;
  int bound_port = 0;
  std::atomic<bool> stopping{false};
  std::thread acceptor;
  std::vector<std::thread> servers;
  std::mutex m;
  std::condition_variable cv;
  std::deque<ConnectionPtr> waiting;   // readable: for the next free thread
  std::deque<ConnectionPtr> returned;  // served and kept alive: for the acceptor to park
  std::atomic<int> open{0};            // connections open: waiting, being served or parked

  void bind_and_listen();
  void accept_loop();
  void serve_loop();
  void wake();
  // One request; false when the connection must close.
  bool serve_one(int fd, TimedSocket& sock, beast::flat_buffer& buf, const std::string& peer, bool last);
};

void Server::Impl::bind_and_listen() {
  const std::string name = where.unix_socket ? "unix:" + where.host : where.host + ":" + std::to_string(where.port);
  if (where.unix_socket) {
    listen_fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (listen_fd < 0) throw std::runtime_error("http: " + name + ": socket: " + std::strerror(errno));
    sockaddr_un sa{};
    sa.sun_family = AF_UNIX;
    std::strncpy(sa.sun_path, where.host.c_str(), sizeof sa.sun_path - 1);
    // A socket file left by a process that is gone is replaced; a live one is not.
    std::error_code ec;
    if (fs::is_socket(where.host, ec)) {
      const int probe = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
      const bool live = ::connect(probe, reinterpret_cast<sockaddr*>(&sa), sizeof sa) == 0;
      ::close(probe);
      if (live) throw std::runtime_error("http: " + name + ": another process is serving it");
      fs::remove(where.host, ec);
    }
    if (::bind(listen_fd, reinterpret_cast<sockaddr*>(&sa), sizeof sa) != 0)
      throw std::runtime_error("http: " + name + ": bind: " + std::strerror(errno));
  } else {
    addrinfo hints{}, *res = nullptr;
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_NUMERICSERV;
    if (int rc = ::getaddrinfo(where.host.c_str(), std::to_string(where.port).c_str(), &hints, &res); rc != 0)
      throw std::runtime_error("http: " + name + ": " + ::gai_strerror(rc));
    std::string error = "no address";
    for (addrinfo* ai = res; ai; ai = ai->ai_next) {
      const int fd = ::socket(ai->ai_family, ai->ai_socktype | SOCK_CLOEXEC, ai->ai_protocol);
      if (fd < 0) continue;
      const int one = 1;
      ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
      if (::bind(fd, ai->ai_addr, ai->ai_addrlen) == 0) {
        listen_fd = fd;
        break;
      }
      error = std::strerror(errno);
      ::close(fd);
    }
    ::freeaddrinfo(res);
    if (listen_fd < 0) throw std::runtime_error("http: " + name + ": bind: " + error);
    sockaddr_storage ss{};
    socklen_t len = sizeof ss;
    ::getsockname(listen_fd, reinterpret_cast<sockaddr*>(&ss), &len);
    bound_port = ss.ss_family == AF_INET6 ? ntohs(reinterpret_cast<sockaddr_in6*>(&ss)->sin6_port)
                                          : ntohs(reinterpret_cast<sockaddr_in*>(&ss)->sin_port);
  }
  if (::listen(listen_fd, 128) != 0) throw std::runtime_error("http: " + name + ": listen: " + std::strerror(errno));
  wake_fd = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
}

void Server::Impl::wake() {
  const std::uint64_t one = 1;
  [[maybe_unused]] auto n = ::write(wake_fd, &one, sizeof one);
}

// Polls the listening socket and every kept-alive connection, so an idle client holds no thread:
// a parked connection that turns readable goes to the serving threads, one idle past
// idle_timeout_ms is closed, and a new one beyond threads + queue open connections gets 503.
void Server::Impl::accept_loop() {
  using clock = std::chrono::steady_clock;
  std::vector<ConnectionPtr> parked;
  std::vector<struct pollfd> p;
  while (!stopping) {
    p.assign({{listen_fd, POLLIN, 0}, {wake_fd, POLLIN, 0}});
    for (const auto& c : parked) p.push_back({c->fd, POLLIN, 0});
    ::poll(p.data(), p.size(), 200);
    if (p[1].revents & POLLIN) {
      std::uint64_t n;
      [[maybe_unused]] auto r = ::read(wake_fd, &n, sizeof n);
    }
    const auto now = clock::now();
    std::vector<ConnectionPtr> still;
    std::size_t readable = 0;
    {
      std::lock_guard<std::mutex> lock(m);
      for (std::size_t k = 0; k < parked.size(); ++k) {
        if (p[k + 2].revents) waiting.push_back(std::move(parked[k])), ++readable;  // a request, or the peer left
        else if (now - parked[k]->idle_since > std::chrono::milliseconds(limits.idle_timeout_ms)) --open;  // closed
        else still.push_back(std::move(parked[k]));
      }
      for (auto& c : returned) still.push_back(std::move(c));
      returned.clear();
    }
    parked = std::move(still);
    for (std::size_t k = 0; k < readable; ++k) cv.notify_one();
    if (!(p[0].revents & POLLIN)) continue;
    sockaddr_storage ss{};
    socklen_t len = sizeof ss;
    const int fd = ::accept4(listen_fd, reinterpret_cast<sockaddr*>(&ss), &len, SOCK_CLOEXEC);
    if (fd < 0) continue;
    auto c = std::make_unique<Connection>(fd, limits.max_header_bytes);
    if (ss.ss_family == AF_INET || ss.ss_family == AF_INET6) {
      const int one = 1;
      ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);  // answers are whole; send them now
      char host[NI_MAXHOST], serv[NI_MAXSERV];
      if (::getnameinfo(reinterpret_cast<sockaddr*>(&ss), len, host, sizeof host, serv, sizeof serv,
                        NI_NUMERICHOST | NI_NUMERICSERV) == 0)
        c->peer = std::string(host) + ":" + serv;
    }
    if (open.load() >= std::max(1, limits.threads) + limits.queue) {
      Response busy = problem(503, "Service Unavailable", "too many connections are open; retry shortly");
      busy.headers.emplace_back("Retry-After", "1");
      write_response(fd, busy, false, false, 1000);
      continue;  // closed with c
    }
    ++open;
    std::lock_guard<std::mutex> lock(m);
    waiting.push_back(std::move(c));
    cv.notify_one();
  }
}

// Serves a connection's requests while they arrive back to back, then hands it back to the acceptor.
void Server::Impl::serve_loop() {
  for (;;) {
    std::unique_lock<std::mutex> lock(m);
    cv.wait(lock, [&] { return stopping || !waiting.empty(); });
    if (waiting.empty()) return;  // stopping
    ConnectionPtr c = std::move(waiting.front());
    waiting.pop_front();
    lock.unlock();
    bool keep = true;
    try {
      TimedSocket sock(c->fd, limits.idle_timeout_ms);
      do {
        sock.set_timeout(limits.idle_timeout_ms);
        ++c->served;
        keep = serve_one(c->fd, sock, c->buf, c->peer, c->served >= limits.max_requests_per_connection) &&
               c->served < limits.max_requests_per_connection && !stopping;
      } while (keep && c->buf.size() > 0);  // pipelined requests already read
    } catch (const std::exception& e) {
      spdlog::warn("http: connection from {} ended: {}", c->peer, e.what());
      keep = false;
    }
    if (!keep) {
      c.reset();
      --open;
      continue;
    }
    c->idle_since = std::chrono::steady_clock::now();
    lock.lock();
    returned.push_back(std::move(c));
    lock.unlock();
    wake();
  }
}

bool Server::Impl::serve_one(int fd, TimedSocket& sock, beast::flat_buffer& buf, const std::string& peer, bool last) {
  const int t = limits.read_timeout_ms;
  const auto refuse = [&](int status, const std::string& title, const std::string& detail) {
    write_response(fd, problem(status, title, detail), false, false, t);
    return false;
  };
  bhttp::request_parser<bhttp::empty_body> head;
  head.header_limit(static_cast<std::uint32_t>(limits.max_header_bytes));
  head.body_limit(std::numeric_limits<std::uint64_t>::max());  // decided per route below
  error_code ec;
  // The first byte may take the idle timeout; the rest of the head the read timeout.
  bhttp::read_header(sock, buf, head, ec);
  if (ec == boost::asio::error::eof || ec == beast::error::timeout) {
    if (ec == beast::error::timeout && buf.size() > 0) return refuse(408, "Request Timeout", "the request head did not arrive in time");
    return false;  // the peer closed or went quiet between requests
  }
  if (ec == bhttp::error::header_limit || ec == bhttp::error::buffer_overflow)
    return refuse(431, "Request Header Fields Too Large",
                  "the request line and headers exceed " + std::to_string(limits.max_header_bytes) + " bytes");
  if (ec) return refuse(400, "Bad Request", "malformed request: " + ec.message());
  sock.set_timeout(t);

  const auto& msg = head.get();
  Request req;
  req.method = std::string(msg.method_string());
  req.target = std::string(msg.target());
  req.peer = peer;
  int fields = 0;
  for (const auto& f : msg) {
    if (++fields > limits.max_headers)
      return refuse(431, "Request Header Fields Too Large", "more than " + std::to_string(limits.max_headers) + " header fields");
    std::string& v = req.headers[lower(std::string(f.name_string()))];
    if (!v.empty()) v += ", ";
    v += std::string(f.value());
  }
  if (msg.version() != 11 && msg.version() != 10) return refuse(505, "HTTP Version Not Supported", "HTTP/1.1 only");
  if (!split_target(req.target, &req)) return refuse(400, "Bad Request", "malformed request target");
  // Bodies are never decoded: an encoded one is refused rather than inflated.
  if (!req.header("content-encoding").empty() && lower(req.header("content-encoding")) != "identity")
    return refuse(415, "Unsupported Media Type", "Content-Encoding is not accepted; send the body unencoded");
  if (const std::string te = lower(req.header("transfer-encoding")); !te.empty() && te != "chunked")
    return refuse(501, "Not Implemented", "Transfer-Encoding other than chunked is not accepted");
  const bool keep_alive = msg.keep_alive() && !last && !stopping;
  const bool has_body = head.chunked() || (head.content_length() && *head.content_length() > 0);
  const bool to_file = has_body && routes.streams_body(req);
  const std::uint64_t cap = to_file ? limits.max_upload_bytes : limits.max_body_bytes;
  if (head.content_length() && *head.content_length() > cap)
    return refuse(413, "Content Too Large", "the body is larger than " + std::to_string(cap) + " bytes");
  if (has_body && lower(req.header("expect")) == "100-continue") {
    const std::string cont = "HTTP/1.1 100 Continue\r\n\r\n";
    if (!send_all(fd, cont.data(), cont.size(), t)) return false;
  }

  struct Removal {
    std::string path;
    ~Removal() {
      std::error_code ec;
      if (!path.empty()) fs::remove(path, ec);
    }
  } removal;
  if (to_file) {
    bhttp::request_parser<bhttp::buffer_body> p(std::move(head));
    p.body_limit(cap);
    req.body_file = removal.path = temp_name(routes.upload_dir);
    std::ofstream out(req.body_file, std::ios::binary | std::ios::trunc);
    if (!out) return refuse(500, "Internal Server Error", "the upload could not be stored");
    Sha256 sha;
    std::vector<char> chunk(1 << 16);
    while (!p.is_done()) {
      p.get().body().data = chunk.data();
      p.get().body().size = chunk.size();
      bhttp::read(sock, buf, p, ec);
      if (ec == bhttp::error::need_buffer) ec = {};
      if (ec == bhttp::error::body_limit)
        return refuse(413, "Content Too Large", "the body is larger than " + std::to_string(cap) + " bytes");
      if (ec == beast::error::timeout) return refuse(408, "Request Timeout", "the body did not arrive in time");
      if (ec) return refuse(400, "Bad Request", "malformed body: " + ec.message());
      const std::size_t n = chunk.size() - p.get().body().size;
      out.write(chunk.data(), static_cast<std::streamsize>(n));
      sha.update(chunk.data(), n);
      req.body_size += n;
    }
    out.close();
    if (!out) return refuse(500, "Internal Server Error", "the upload could not be stored");
    req.body_sha256 = sha.hex();
  } else if (has_body) {
    bhttp::request_parser<bhttp::string_body> p(std::move(head));
    p.body_limit(cap);
    bhttp::read(sock, buf, p, ec);
    if (ec == bhttp::error::body_limit)
      return refuse(413, "Content Too Large", "the body is larger than " + std::to_string(cap) + " bytes");
    if (ec == beast::error::timeout) return refuse(408, "Request Timeout", "the body did not arrive in time");
    if (ec) return refuse(400, "Bad Request", "malformed body: " + ec.message());
    req.body = std::move(p.get().body());
  }

  Response res;
  try {
    res = routes.handle(req);
  } catch (const std::exception& e) {
    spdlog::error("http: {} {}: {}", req.method, req.path, e.what());
    res = problem(500, "Internal Server Error", "the request failed inside the server; see its log");
  }
  const bool sent = write_response(fd, res, keep_alive, req.method == "HEAD", t);
  if (res.remove_file && !res.file.empty()) {
    std::error_code ec;
    fs::remove(res.file, ec);
  }
  return sent && keep_alive;
}

Server::Server(ListenAddress where, Limits limits, Routes routes) : impl_(std::make_unique<Impl>()) {
  impl_->where = std::move(where);
  impl_->limits = limits;
  impl_->routes = std::move(routes);
}

Server::~Server() { stop(); }

void Server::start() {
  if (sodium_init() < 0) throw std::runtime_error("http: libsodium failed to initialise");
  impl_->bind_and_listen();
  for (int k = 0; k < std::max(1, impl_->limits.threads); ++k) impl_->servers.emplace_back([this] { impl_->serve_loop(); });
  impl_->acceptor = std::thread([this] { impl_->accept_loop(); });
}

void Server::stop() {
  if (!impl_ || impl_->stopping.exchange(true)) return;
  if (impl_->wake_fd >= 0) impl_->wake();
  if (impl_->acceptor.joinable()) impl_->acceptor.join();
  impl_->cv.notify_all();
  for (auto& t : impl_->servers)
    if (t.joinable()) t.join();
  impl_->waiting.clear();  // closes them
  impl_->returned.clear();
  if (impl_->listen_fd >= 0) ::close(impl_->listen_fd);
  if (impl_->wake_fd >= 0) ::close(impl_->wake_fd);
  if (impl_->where.unix_socket && impl_->listen_fd >= 0) {
    std::error_code ec;
    fs::remove(impl_->where.host, ec);
  }
  impl_->listen_fd = impl_->wake_fd = -1;
}

int Server::port() const { return impl_->bound_port; }

std::string Server::address() const {
  return impl_->where.unix_socket ? "unix:" + impl_->where.host
                                  : impl_->where.host + ":" + std::to_string(impl_->bound_port);
}

}  // namespace mm::http
