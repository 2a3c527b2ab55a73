// Drop folders: a file placed in <drop>/protect/<customer>/ becomes a protect job for that
// customer, one placed in <drop>/detect/ a detect job. When its job is final the file moves to
// <drop>/done/... or <drop>/failed/... (same relative path) with <name>.json beside it saying why.
//
// Only complete files are picked up: a file renamed in (IN_MOVED_TO) is ready at once, the safe way
// to drop; a file written in place is ready once closed and its size and mtime have not changed
// for settle_ms (a client may open, append and close it several times); so are files found by
// scanning (present at start, missed events, no inotify).
// Ignored: symlinks and anything not a regular file, dotfiles and temporary names (*.tmp, *.part,
// *~, *.swp, *.crdownload, #*#), customer folders that are symlinks or not valid customer names,
// and anything whose path would leave the drop folder.
#pragma once
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace mm::service {

enum class DropKind { protect, detect };

struct DropItem {
  DropKind kind = DropKind::protect;
  std::string customer;  // protect only
  std::string name;      // file name
  std::string path;      // absolute path in the drop folder
  std::string relative;  // "protect/<customer>/<name>" or "detect/<name>"
};

bool is_ignored_name(const std::string& name);       // dotfiles and temporary names
bool is_valid_customer_name(const std::string& name);  // [A-Za-z0-9._-]{1,64}, no leading dot
// Classifies `relative` (a path below the drop root): nullopt with `why` set when it is not a
// drop item (wrong depth, unknown area, escaping name, ignored name, symlink, not a file...).
std::optional<DropItem> classify_drop_path(const std::string& drop_root, const std::string& relative,
                                           std::string* why = nullptr);

// Removes hidden temporary reason files (".<name>.json.tmp.XXXXXX") a crash left in done/ and
// failed/. Call at start, before any finish(). Returns how many were removed.
int remove_stale_reason_temps(const std::string& drop_root);

class DropWatcher {
 public:
  DropWatcher(std::string drop_root, bool use_inotify, int settle_ms);
  ~DropWatcher();
  DropWatcher(const DropWatcher&) = delete;
  DropWatcher& operator=(const DropWatcher&) = delete;

  int fd() const { return inotify_fd_; }  // -1 when polling only
  bool inotify_active() const { return inotify_fd_ >= 0; }
  void set_settle_ms(int ms) { settle_ms_ = ms; }

  // Reads pending inotify events (non-blocking), rescans, and returns the files that became
  // ready since the last call. A file is returned once until forget(path) is called.
  std::vector<DropItem> poll(std::int64_t now_ms);
  void forget(const std::string& path);
  // One-shot scan for batch runs (no waiting): files whose mtime is at least settle_ms old.
  std::vector<DropItem> scan_once(std::int64_t now_ms);

  // Moves the item to <drop>/done/<relative> (ok) or <drop>/failed/<relative>, writing
  // <destination>.json with `reason_json` first. Never overwrites: a taken name gets "-1", "-2"...
  // Returns the destination path.
  static std::string finish(const std::string& drop_root, const DropItem& item, bool ok,
                            const std::string& reason_json);

 private:
  struct Seen {
    std::uintmax_t size = 0;
    std::int64_t mtime_ns = 0;
    std::int64_t since_ms = 0;  // when (size, mtime) were first seen unchanged
  };
  void add_watch(const std::string& dir);
  void read_events(std::int64_t now_ms);
  void scan(std::int64_t now_ms);
  void consider(const std::string& relative, std::int64_t now_ms, bool closed);

  std::string root_;
  int settle_ms_;
  bool age_only_ = false;
  int inotify_fd_ = -1;
  std::map<int, std::string> watches_;   // wd -> relative folder ("protect", "protect/acme", "detect")
  std::set<std::string> writing_;        // created while watched, not closed yet (relative)
  std::map<std::string, Seen> seen_;     // scan observations (relative)
  std::set<std::string> reported_;       // returned and not yet forgotten (absolute)
  std::vector<DropItem> ready_;
};

}  // namespace mm::service
