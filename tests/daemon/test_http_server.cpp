// The HTTP server under hostile requests: each is refused with its status and reason, and the
// server goes on serving.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <string>
#include <thread>

#include "http/server.h"

namespace {

using namespace mm::http;
namespace fs = std::filesystem;

int connect_tcp(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in sa{};
  sa.sin_family = AF_INET;
  sa.sin_port = htons(static_cast<uint16_t>(port));
  sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&sa), sizeof sa) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

void send_text(int fd, const std::string& s) {
  std::size_t done = 0;
  while (done < s.size()) {
    const ssize_t n = ::send(fd, s.data() + done, s.size() - done, MSG_NOSIGNAL);
    if (n <= 0) return;  // the server may close early on a refusal
    done += static_cast<std::size_t>(n);
  }
}

// Everything the server sends until it closes (or `timeout_ms` of silence).
std::string read_all(int fd, int timeout_ms = 5000) {
  std::string out;
  char buf[4096];
  for (;;) {
    struct pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) break;
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    out.append(buf, static_cast<std::size_t>(n));
  }
  return out;
}

std::string exchange(int port, const std::string& raw) {
  const int fd = connect_tcp(port);
  if (fd < 0) return "connect failed";
  send_text(fd, raw);
  std::string r = read_all(fd);
  ::close(fd);
  return r;
}

int status_of(const std::string& response) {
  if (response.rfind("HTTP/1.1 ", 0) != 0) return -1;
  return std::stoi(response.substr(9, 3));
}

std::string body_of(const std::string& response) {
  const auto at = response.find("\r\n\r\n");
  return at == std::string::npos ? "" : response.substr(at + 4);
}

// A fresh folder per test, removed afterwards.
struct TempDir {
  fs::path path;
  TempDir() {
    std::string t = (fs::temp_directory_path() / "mm_http_XXXXXX").string();
    path = ::mkdtemp(t.data());
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

struct ServerFixture : ::testing::Test {
  TempDir dir;
  Limits limits;
  std::unique_ptr<Server> server;
  std::atomic<int> handled{0};
  Request last;  // the last request handled (one at a time in these tests)

  void start(const std::string& listen = "127.0.0.1:0") {
    Routes routes;
    routes.upload_dir = dir.path.string();
    routes.streams_body = [](const Request& r) { return r.path == "/upload"; };
    routes.handle = [this](Request& r) {
      ++handled;
      last = r;
      Response res;
      if (r.path == "/upload") {
        std::ifstream in(r.body_file, std::ios::binary);
        res.body = std::string(r.body_sha256) + " " + std::to_string(r.body_size) + (in ? " present" : " missing");
      } else if (r.path == "/file") {
        res.file = (dir.path / "served.bin").string();
        res.content_type = "application/octet-stream";
      } else {
        res.body = "{\"path\":\"" + r.path + "\",\"bytes\":" + std::to_string(r.body.size()) + "}";
      }
      return res;
    };
    server = std::make_unique<Server>(parse_listen(listen), limits, routes);
    server->start();
  }
  int port() const { return server->port(); }
  // Within two seconds (connections the test closed may still be leaving the queue).
  void expect_still_serving() {
    std::string r;
    for (int k = 0; k < 20; ++k) {
      r = exchange(port(), "GET /ping HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
      if (status_of(r) == 200) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    EXPECT_EQ(status_of(r), 200) << r;
  }
};

TEST(HttpListen, ParsesAddressesAndRefusesBadOnes) {
  EXPECT_EQ(parse_listen("127.0.0.1:8440").port, 8440);
  EXPECT_EQ(parse_listen("[::1]:9").host, "::1");
  EXPECT_TRUE(parse_listen("unix:/run/meshmark/api.sock").unix_socket);
  EXPECT_THROW(parse_listen("unix:relative.sock"), std::invalid_argument);
  EXPECT_THROW(parse_listen("localhost"), std::invalid_argument);
  EXPECT_THROW(parse_listen("localhost:http"), std::invalid_argument);
  EXPECT_THROW(parse_listen("localhost:70000"), std::invalid_argument);
}

TEST_F(ServerFixture, AnswersAndKeepsTheConnectionAlive) {
  start();
  const int fd = connect_tcp(port());
  send_text(fd, "GET /a?x=1%202&y=%2F HTTP/1.1\r\nHost: x\r\n\r\nGET /b HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
  const std::string r = read_all(fd);
  ::close(fd);
  EXPECT_NE(r.find("{\"path\":\"/a\""), std::string::npos) << r;
  EXPECT_NE(r.find("{\"path\":\"/b\""), std::string::npos) << r;
  EXPECT_EQ(handled.load(), 2);
  EXPECT_EQ(last.path, "/b");
}

TEST_F(ServerFixture, DecodesTheQuery) {
  start();
  exchange(port(), "GET /q?name=a%20b+c&flag HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
  EXPECT_EQ(last.query["name"], "a b c");
  EXPECT_EQ(last.query.count("flag"), 1u);
  const std::string bad = exchange(port(), "GET /q?name=%zz HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_EQ(status_of(bad), 400) << bad;
  EXPECT_NE(bad.find("application/problem+json"), std::string::npos);
}

TEST_F(ServerFixture, RefusesABodyOverTheLimitByItsLength) {
  limits.max_body_bytes = 100;
  start();
  const std::string r = exchange(port(), "POST /j HTTP/1.1\r\nHost: x\r\nContent-Length: 5000000000\r\n\r\n{}");
  EXPECT_EQ(status_of(r), 413) << r;
  EXPECT_NE(body_of(r).find("larger than 100 bytes"), std::string::npos) << r;
  EXPECT_EQ(handled.load(), 0);
  expect_still_serving();
}

TEST_F(ServerFixture, RefusesAnEndlessChunkedBody) {
  limits.max_body_bytes = 1000;
  start();
  const int fd = connect_tcp(port());
  send_text(fd, "POST /j HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n");
  const std::string chunk = "100\r\n" + std::string(256, 'a') + "\r\n";
  for (int k = 0; k < 64; ++k) send_text(fd, chunk);  // 16 KiB and no end
  const std::string r = read_all(fd);
  ::close(fd);
  EXPECT_EQ(status_of(r), 413) << r;
  EXPECT_EQ(handled.load(), 0);
  expect_still_serving();
}

TEST_F(ServerFixture, RefusesTooManyHeadersAndTooLongHeads) {
  limits.max_headers = 20;
  limits.max_header_bytes = 4096;
  start();
  std::string many = "GET /h HTTP/1.1\r\nHost: x\r\n";
  for (int k = 0; k < 30; ++k) many += "X-" + std::to_string(k) + ": 1\r\n";
  const std::string r1 = exchange(port(), many + "\r\n");
  EXPECT_EQ(status_of(r1), 431) << r1;
  const std::string r2 = exchange(port(), "GET /h HTTP/1.1\r\nHost: x\r\nX-Big: " + std::string(10000, 'b') + "\r\n\r\n");
  EXPECT_EQ(status_of(r2), 431) << r2;
  EXPECT_EQ(handled.load(), 0);
  expect_still_serving();
}

TEST_F(ServerFixture, RefusesTransferEncodingBesideContentLength) {
  start();
  // The classic request-smuggling pair: whichever length a proxy believes, the server refuses.
  const std::string r1 = exchange(port(), "POST /j HTTP/1.1\r\nHost: x\r\nContent-Length: 4\r\nTransfer-Encoding: chunked\r\n\r\n"
                                          "0\r\n\r\nGET /smuggled HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_EQ(status_of(r1), 400) << r1;
  const std::string r2 = exchange(port(), "POST /j HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\nContent-Length: 4\r\n\r\n"
                                          "0\r\n\r\n");
  EXPECT_EQ(status_of(r2), 400) << r2;
  const std::string r3 = exchange(port(), "POST /j HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: gzip, chunked, identity\r\n\r\n");
  EXPECT_EQ(status_of(r3), 501) << r3;
  EXPECT_EQ(handled.load(), 0);
  expect_still_serving();
}

TEST_F(ServerFixture, NeverInflatesAnEncodedBody) {
  start();
  const std::string r = exchange(port(), "POST /j HTTP/1.1\r\nHost: x\r\nContent-Encoding: gzip\r\nContent-Length: 3\r\n\r\nabc");
  EXPECT_EQ(status_of(r), 415) << r;
  EXPECT_EQ(handled.load(), 0);
  expect_still_serving();
}

TEST_F(ServerFixture, ClosesASlowRequestAfterTheReadTimeout) {
  limits.read_timeout_ms = 300;
  limits.idle_timeout_ms = 300;
  start();
  const int fd = connect_tcp(port());
  send_text(fd, "GET /slow HTTP/1.1\r\nHost: x\r\n");  // and never the blank line
  const auto t0 = std::chrono::steady_clock::now();
  const std::string r = read_all(fd, 5000);
  const auto waited = std::chrono::steady_clock::now() - t0;
  ::close(fd);
  EXPECT_EQ(status_of(r), 408) << r;
  EXPECT_LT(waited, std::chrono::seconds(4));
  expect_still_serving();
}

TEST_F(ServerFixture, AnswersBusyWhenTheQueueIsFull) {
  limits.threads = 1;
  limits.queue = 1;
  limits.idle_timeout_ms = 3000;
  start();
  const int a = connect_tcp(port());  // taken by the one thread, idle
  send_text(a, "GET /a HTTP/1.1\r\nHost: x\r\n\r\n");
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const int b = connect_tcp(port());  // waits in the queue
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const int c = connect_tcp(port());  // no room
  const std::string rc = read_all(c, 2000);
  EXPECT_EQ(status_of(rc), 503) << rc;
  EXPECT_NE(rc.find("Retry-After: 1"), std::string::npos);
  ::close(a);
  ::close(b);
  ::close(c);
  expect_still_serving();
}

TEST_F(ServerFixture, StreamsAnUploadToAFileWithItsHash) {
  limits.max_body_bytes = 10;  // uploads have their own limit
  limits.max_upload_bytes = 1 << 20;
  start();
  const std::string body(300000, 'z');
  const std::string r = exchange(port(), "POST /upload HTTP/1.1\r\nHost: x\r\nContent-Length: " + std::to_string(body.size()) +
                                             "\r\nConnection: close\r\n\r\n" + body);
  EXPECT_EQ(status_of(r), 200) << r;
  // sha256 of 300,000 'z' bytes, computed with sha256sum.
  EXPECT_EQ(body_of(r).substr(65), "300000 present");
  EXPECT_EQ(last.body_sha256.size(), 64u);
  EXPECT_FALSE(fs::exists(last.body_file)) << "the upload's temporary file is removed after the request";
  const std::string big = exchange(port(), "POST /upload HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n" +
                                               std::string("100000\r\n") + std::string(0x100000, 'y') + "\r\n" +
                                               "10\r\n" + std::string(16, 'y') + "\r\n0\r\n\r\n");
  EXPECT_EQ(status_of(big), 413) << big.substr(0, 200);
  int leftovers = 0;
  for (const auto& e : fs::directory_iterator(dir.path)) leftovers += e.path().filename().string().rfind(".upload-", 0) == 0;
  EXPECT_EQ(leftovers, 0) << "a refused upload leaves nothing behind";
}

TEST_F(ServerFixture, SendsAFile) {
  start();
  std::ofstream(dir.path / "served.bin", std::ios::binary) << std::string(200000, 'q');
  const std::string r = exchange(port(), "GET /file HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
  EXPECT_EQ(status_of(r), 200);
  EXPECT_NE(r.find("Content-Length: 200000"), std::string::npos);
  EXPECT_EQ(body_of(r), std::string(200000, 'q'));
}

TEST_F(ServerFixture, ServesOnAUnixSocket) {
  const std::string path = (dir.path / "api.sock").string();
  start("unix:" + path);
  const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
  sockaddr_un sa{};
  sa.sun_family = AF_UNIX;
  std::strncpy(sa.sun_path, path.c_str(), sizeof sa.sun_path - 1);
  ASSERT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&sa), sizeof sa), 0);
  send_text(fd, "GET /u HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
  const std::string r = read_all(fd);
  ::close(fd);
  EXPECT_EQ(status_of(r), 200) << r;
  EXPECT_EQ(last.peer, "unix");
  server->stop();
  EXPECT_FALSE(fs::exists(path)) << "the socket file is removed on stop";
}

}  // namespace
