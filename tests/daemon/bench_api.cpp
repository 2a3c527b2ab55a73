// meshmarkd's HTTP API under load (Google Benchmark; run by scripts/bench-api.sh). Each case starts
// the real meshmarkd on loopback with 2 workers and measures it from outside:
//  - BM_PollersWhileJobsRun: 200 clients, each on its own kept-alive connection, poll a job's
//    status (3 in 4) or the queue counts every 100 ms while 1,000 protect jobs (abc7, one
//    customer, 1,000 part names) are submitted through the API and run, until every job is final.
//    Counters: requests answered, errors (anything but the expected status, or a broken
//    connection), latency p50, p99 and max in ms, the time to submit and to finish the jobs.
//  - BM_Upload500MB: one 500 MB part streamed to POST /v1/parts; the daemon's peak RSS (VmHWM)
//    before and after, so the upload's cost in memory is their difference.
//  - BM_HostileRequests: the refused requests of tests/daemon/test_http_server.cpp sent 200 times
//    each, interleaved with status requests: every hostile one refused, every status one answered.
#include <arpa/inet.h>
#include <benchmark/benchmark.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>
#include <vector>

#include "common/free_port.h"
#include "store/home.h"
#include "store/store.h"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using clock_type = std::chrono::steady_clock;

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  return std::string((std::istreambuf_iterator<char>(in)), {});
}

// One kept-alive HTTP/1.1 connection; every answer must carry Content-Length (the API's do).
class Client {
 public:
  explicit Client(int port) : port_(port) {}
  ~Client() { close(); }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  // The status code, or 0 when the connection broke; the body in *body.
  int request(const std::string& method, const std::string& target, const std::string& token,
              const std::string& body = "", std::string* out = nullptr, const std::string& extra = "") {
    if (fd_ < 0 && !connect()) return 0;
    std::string req = method + " " + target + " HTTP/1.1\r\nHost: bench\r\nAuthorization: Bearer " + token + "\r\n" + extra;
    if (method == "POST") req += "Content-Type: application/json\r\nContent-Length: " + std::to_string(body.size()) + "\r\n";
    req += "\r\n" + body;
    if (!send_all(req)) return fail();
    return read_reply(out);
  }
  bool send_all(const std::string& data) {
    for (std::size_t sent = 0; sent < data.size();) {
      const ssize_t n = ::send(fd_, data.data() + sent, data.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) return false;
      sent += static_cast<std::size_t>(n);
    }
    return true;
  }
  bool connect() {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in sa{};
    sa.sin_family = AF_INET;
    sa.sin_port = htons(static_cast<uint16_t>(port_));
    sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&sa), sizeof sa) == 0) return true;
    close();
    return false;
  }
  int fd() const { return fd_; }
  int read_reply(std::string* out) {
    std::size_t head_end;
    while ((head_end = buf_.find("\r\n\r\n")) == std::string::npos)
      if (!receive()) return fail();
    const std::string head = buf_.substr(0, head_end);
    std::size_t length = 0;
    const auto cl = head.find("Content-Length: ");
    if (cl != std::string::npos) length = std::stoull(head.substr(cl + 16));
    while (buf_.size() < head_end + 4 + length)
      if (!receive()) return fail();
    if (out) *out = buf_.substr(head_end + 4, length);
    buf_.erase(0, head_end + 4 + length);
    if (head.find("Connection: close") != std::string::npos) close();
    return head.size() >= 12 ? std::stoi(head.substr(9, 3)) : 0;
  }

 private:
  bool receive() {
    struct pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, 30000) <= 0) return false;
    char b[16384];
    const ssize_t n = ::recv(fd_, b, sizeof b, 0);
    if (n <= 0) return false;
    buf_.append(b, static_cast<std::size_t>(n));
    return true;
  }
  int fail() {
    close();
    buf_.clear();
    return 0;
  }
  int port_;
  int fd_ = -1;
  std::string buf_;
};

// A meshmarkd with its HTTP API on a free loopback port, in a folder of its own.
struct RunningDaemon {
  fs::path dir;
  int port = 0;
  pid_t pid = -1;
  std::string token;
  explicit RunningDaemon(const std::string& tag, std::int64_t max_input_bytes = 256ll << 20) {
    dir = fs::temp_directory_path() / ("mm-bench-api-" + tag + "-" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir / "drop");
    fs::create_directories(dir / "out");
    ::unsetenv("MESHMARK_MASTER_KEY");
    const auto paths = mm::store::resolve_home((dir / "home").string());
    mm::store::init_home(paths);
    {
      auto st = mm::store::open_home(paths, true);
      token = st->create_token("bench", mm::store::TokenRole::admin).secret;
      st->add_customer("acme", "bench");
    }
    port = mm::test::free_port();
    std::ofstream(dir / "meshmarkd.json")
        << json{{"home", (dir / "home").string()}, {"drop_dir", (dir / "drop").string()},
                {"output_dir", (dir / "out").string()}, {"workers", 2}, {"poll_interval_ms", 50},
                {"max_input_bytes", max_input_bytes}, {"log_file", (dir / "meshmarkd.log").string()},
                {"http", {{"listen", "127.0.0.1:" + std::to_string(port)}, {"threads", 4}}}}
               .dump(2);
    pid = ::fork();
    if (pid == 0) {
      const std::string cfg = (dir / "meshmarkd.json").string();
      ::execl(MESHMARKD_EXE, MESHMARKD_EXE, "--config", cfg.c_str(), static_cast<char*>(nullptr));
      std::_Exit(127);
    }
    const auto end = clock_type::now() + std::chrono::seconds(30);
    while (clock_type::now() < end) {
      Client c(port);
      if (c.request("GET", "/healthz", token) == 200) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    throw std::runtime_error("meshmarkd did not start: " + slurp(dir / "meshmarkd.log"));
  }
  ~RunningDaemon() {
    ::kill(pid, SIGTERM);
    int st = 0;
    ::waitpid(pid, &st, 0);
    fs::remove_all(dir);
  }
  // The daemon's peak resident set (VmHWM) in MB.
  double peak_rss_mb() const {
    std::ifstream in("/proc/" + std::to_string(pid) + "/status");
    for (std::string line; std::getline(in, line);)
      if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
    return 0;
  }
};

double percentile(std::vector<double>& v, double q) {
  if (v.empty()) return 0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

void BM_PollersWhileJobsRun(benchmark::State& state) {
  const int kJobs = 1000, kPollers = static_cast<int>(state.range(0));
  for (auto _ : state) {
    RunningDaemon d("poll");
    Client admin(d.port);
    std::string reply;
    std::ifstream in(std::string(MESHMARK_SHARED_MESHES) + "/abc7.stl", std::ios::binary);
    const std::string part((std::istreambuf_iterator<char>(in)), {});
    if (part.empty()) {
      state.SkipWithError("the shared mesh abc7.stl is absent (../shared/data/meshes)");
      return;
    }
    std::string req = "POST /v1/parts?name=abc7.stl HTTP/1.1\r\nHost: bench\r\nAuthorization: Bearer " + d.token +
                      "\r\nContent-Length: " + std::to_string(part.size()) + "\r\n\r\n" + part;
    if (!admin.connect() || !admin.send_all(req) || admin.read_reply(&reply) != 201) {
      state.SkipWithError(("upload refused: " + reply).c_str());
      return;
    }
    const std::string sha = json::parse(reply)["sha256"];
    std::atomic<bool> done{false};
    std::atomic<long> errors{0}, answered{0};
    std::mutex m;
    std::vector<std::int64_t> ids;  // submitted so far (under m)
    std::vector<double> latencies;
    std::vector<std::thread> pollers;
    for (int p = 0; p < kPollers; ++p)
      pollers.emplace_back([&, p] {
        std::mt19937 rng(static_cast<unsigned>(p));
        Client c(d.port);
        std::vector<double> mine;
        std::string body;
        for (int k = 0; !done; ++k) {
          std::string target = "/v1/queue";
          if (k % 4 != 3) {
            std::lock_guard<std::mutex> l(m);
            if (!ids.empty()) target = "/v1/jobs/" + std::to_string(ids[rng() % ids.size()]);
          }
          const auto s = clock_type::now();
          const int status = c.request("GET", target, d.token, "", &body);
          mine.push_back(std::chrono::duration<double, std::milli>(clock_type::now() - s).count());
          if (status == 200) ++answered;
          else ++errors;
          std::this_thread::sleep_for(std::chrono::milliseconds(100));  // a poller's interval
        }
        std::lock_guard<std::mutex> l(m);
        latencies.insert(latencies.end(), mine.begin(), mine.end());
      });
    // The jobs are submitted while the pollers run.
    const auto t0 = clock_type::now();
    for (int k = 0; k < kJobs; ++k) {
      const std::string body =
          json{{"part", {{"sha256", sha}, {"name", "part-" + std::to_string(k) + ".stl"}}}, {"customers", {"acme"}}}.dump();
      if (admin.request("POST", "/v1/jobs/protect", d.token, body, &reply) != 202) {
        ++errors;
        continue;
      }
      std::lock_guard<std::mutex> l(m);
      ids.push_back(json::parse(reply)["jobs"][0]["id"].get<std::int64_t>());
    }
    const double submit_s = std::chrono::duration<double>(clock_type::now() - t0).count();
    // Done when the queue has no job left to run.
    for (;;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
      if (admin.request("GET", "/v1/queue", d.token, "", &reply) != 200) continue;
      const json q = json::parse(reply);
      if (q["queued"].get<long>() + q["running"].get<long>() + q["retrying"].get<long>() == 0) break;
    }
    const double jobs_s = std::chrono::duration<double>(clock_type::now() - t0).count();
    done = true;
    for (auto& t : pollers) t.join();
    admin.request("GET", "/v1/queue", d.token, "", &reply);
    const json q = json::parse(reply);
    state.counters["jobs_succeeded"] = q["succeeded"].get<double>();
    state.counters["jobs_failed"] = q["failed"].get<double>();
    state.counters["jobs_wall_s"] = jobs_s;
    state.counters["submit_s"] = submit_s;
    state.counters["requests"] = static_cast<double>(answered.load());
    state.counters["errors"] = static_cast<double>(errors.load());
    state.counters["p50_ms"] = percentile(latencies, 0.50);
    state.counters["p99_ms"] = percentile(latencies, 0.99);
    state.counters["max_ms"] = latencies.empty() ? 0 : *std::max_element(latencies.begin(), latencies.end());
    state.counters["daemon_peak_rss_mb"] = d.peak_rss_mb();
  }
}
BENCHMARK(BM_PollersWhileJobsRun)->Arg(200)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

void BM_Upload500MB(benchmark::State& state) {
  const std::uint64_t kBytes = 500ull << 20;
  for (auto _ : state) {
    RunningDaemon d("upload", 600ll << 20);
    const double before = d.peak_rss_mb();
    Client c(d.port);
    if (!c.connect()) {
      state.SkipWithError("no connection");
      return;
    }
    const std::string head = "POST /v1/parts?name=big.stl HTTP/1.1\r\nHost: bench\r\nAuthorization: Bearer " + d.token +
                             "\r\nContent-Length: " + std::to_string(kBytes) + "\r\n\r\n";
    std::string chunk(1 << 20, '\0');
    std::mt19937_64 rng(7);
    for (auto& ch : chunk) ch = static_cast<char>(rng());
    const auto t0 = clock_type::now();
    bool ok = c.send_all(head);
    for (std::uint64_t sent = 0; ok && sent < kBytes; sent += chunk.size()) ok = c.send_all(chunk);
    std::string reply;
    const int status = ok ? c.read_reply(&reply) : 0;
    const double seconds = std::chrono::duration<double>(clock_type::now() - t0).count();
    if (status != 201) {
      state.SkipWithError(("upload refused: " + std::to_string(status) + " " + reply).c_str());
      return;
    }
    state.counters["upload_MB_s"] = 500.0 / seconds;
    state.counters["daemon_peak_rss_before_mb"] = before;
    state.counters["daemon_peak_rss_after_mb"] = d.peak_rss_mb();
  }
}
BENCHMARK(BM_Upload500MB)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

void BM_HostileRequests(benchmark::State& state) {
  // Each one, sent raw on a fresh connection, and the status a clean refusal has.
  const std::vector<std::pair<std::string, int>> hostile = {
      {"POST /v1/jobs/detect HTTP/1.1\r\nHost: b\r\nContent-Length: 5\r\nTransfer-Encoding: chunked\r\n\r\n0\r\n\r\n", 400},
      {"POST /v1/jobs/detect HTTP/1.1\r\nHost: b\r\nTransfer-Encoding: gzip\r\n\r\n", 501},
      {"POST /v1/jobs/detect HTTP/1.1\r\nHost: b\r\nContent-Encoding: gzip\r\nContent-Length: 3\r\n\r\nabc", 415},
      {"GET /healthz HTTP/1.1\r\nHost: b\r\nX-Big: " + std::string(20000, 'a') + "\r\n\r\n", 431},
      {"POST /v1/jobs/detect HTTP/1.1\r\nHost: b\r\nContent-Length: 999999999\r\n\r\n", 413},
      {"GET /v1/queue HTTP/1.1\r\nHost: b\r\nAuthorization: Bearer mmt_forged\r\n\r\n", 401},
  };
  for (auto _ : state) {
    RunningDaemon d("hostile");
    long refused = 0, wrong = 0, served = 0;
    for (int round = 0; round < 200; ++round)
      for (const auto& [text, expected] : hostile) {
        Client h(d.port);
        std::string body;
        const int status = h.connect() && h.send_all(text) ? h.read_reply(&body) : 0;
        (status == expected ? refused : wrong) += 1;
        Client ok(d.port);
        (ok.request("GET", "/v1/queue", d.token) == 200 ? served : wrong) += 1;
      }
    state.counters["refused"] = static_cast<double>(refused);
    state.counters["wrong_answers"] = static_cast<double>(wrong);
    state.counters["served_between"] = static_cast<double>(served);
  }
}
BENCHMARK(BM_HostileRequests)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
