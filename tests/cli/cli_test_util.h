// Running the built `meshmark` binary in a scratch folder, for the offline CLI tests.
#pragma once
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace mm::test {

namespace fs = std::filesystem;

// A scratch folder per test, removed afterwards.
struct Scratch {
  fs::path dir;
  Scratch() {
    static int counter = 0;
    dir = fs::temp_directory_path() /
          ("mm_cli_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  std::string operator/(const std::string& name) const { return (dir / name).string(); }
};

struct CliRun {
  int code = -1;
  std::string out, err;
};

inline std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

inline std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

inline bool exists(const std::string& path) { return fs::exists(path); }

// Runs `meshmark args...`; stdout and stderr are captured through files in the scratch folder.
inline CliRun meshmark(const Scratch& s, const std::vector<std::string>& args) {
  std::string cmd = quote(MESHMARK_EXE);
  for (const auto& a : args) cmd += " " + quote(a);
  const std::string out = s / ".stdout", err = s / ".stderr";
  cmd += " >" + quote(out) + " 2>" + quote(err);
  const int status = std::system(cmd.c_str());
  CliRun r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = slurp(out);
  r.err = slurp(err);
  fs::remove(out);
  fs::remove(err);
  return r;
}

// A fixed key file (tests are reproducible: no random keys), mode 0600 like keygen's.
inline std::string write_key(const Scratch& s, const std::string& name, char fill) {
  const std::string path = s / name;
  std::ofstream(path) << std::string(64, fill) << "\n";
  fs::permissions(path, fs::perms::owner_read | fs::perms::owner_write);
  return path;
}

}  // namespace mm::test
