#include "service/drop_watcher.h"

#include <fcntl.h>
#include <sys/inotify.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <spdlog/spdlog.h>
#include <system_error>

#include "support/atomic_file.h"

namespace mm::service {

namespace fs = std::filesystem;

namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// A single path component that cannot climb out or hide a separator.
bool safe_component(const std::string& c) {
  return !c.empty() && c != "." && c != ".." && c.find('/') == std::string::npos &&
         c.find('\0') == std::string::npos && c.size() <= 255;
}

bool lstat_is(const std::string& path, mode_t type) {
  struct stat st;
  if (::lstat(path.c_str(), &st) != 0) return false;
  return (st.st_mode & S_IFMT) == type;
}

// Hidden temporary name (support/atomic_file.h): scanners of done/ and failed/ skip dotfiles,
// and a crash leaves a name remove_stale_reason_temps() recognises.
void write_text_atomic(const std::string& path, const std::string& text) {
  try {
    support::write_file_atomic(path, text);
  } catch (const std::system_error& e) {
    throw std::system_error(e.code(), path + ": " + e.what());
  }
}

}  // namespace

bool is_ignored_name(const std::string& name) {
  if (name.empty() || name[0] == '.') return true;
  if (name.front() == '#' && name.back() == '#') return true;
  for (const char* s : {".tmp", ".part", "~", ".swp", ".swx", ".crdownload", ".partial"})
    if (ends_with(name, s)) return true;
  return false;
}

bool is_valid_customer_name(const std::string& name) {
  if (name.empty() || name.size() > 64 || name[0] == '.') return false;
  for (char c : name)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-')) return false;
  return true;
}

std::optional<DropItem> classify_drop_path(const std::string& drop_root, const std::string& relative,
                                           std::string* why) {
  auto no = [&](const std::string& reason) -> std::optional<DropItem> {
    if (why) *why = reason;
    return std::nullopt;
  };
  if (relative.empty() || relative[0] == '/') return no("not a relative path");
  std::vector<std::string> parts;
  std::size_t start = 0;
  while (true) {
    auto slash = relative.find('/', start);
    parts.push_back(relative.substr(start, slash == std::string::npos ? std::string::npos : slash - start));
    if (slash == std::string::npos) break;
    start = slash + 1;
  }
  for (const auto& p : parts)
    if (!safe_component(p)) return no("unsafe path component \"" + p + "\"");
  DropItem item;
  if (parts[0] == "protect") {
    if (parts.size() != 3) return no("protect drops must be protect/<customer>/<file>");
    if (!is_valid_customer_name(parts[1])) return no("invalid customer folder name \"" + parts[1] + "\"");
    item.kind = DropKind::protect;
    item.customer = parts[1];
    item.name = parts[2];
  } else if (parts[0] == "detect") {
    if (parts.size() != 2) return no("detect drops must be detect/<file>");
    item.kind = DropKind::detect;
    item.name = parts[1];
  } else {
    return no("not under protect/ or detect/");
  }
  if (is_ignored_name(item.name)) return no("ignored name (dotfile or temporary)");
  // Every folder on the way and the file itself must be real (no symlinks), so the path cannot
  // lead outside the drop folder.
  std::string dir = drop_root;
  for (std::size_t i = 0; i + 1 < parts.size(); ++i) {
    dir += "/" + parts[i];
    if (!lstat_is(dir, S_IFDIR)) return no("folder " + dir + " is a symlink or not a folder");
  }
  item.path = drop_root + "/" + relative;
  if (!lstat_is(item.path, S_IFREG)) return no("not a regular file (symlink, folder or gone)");
  item.relative = relative;
  return item;
}

DropWatcher::DropWatcher(std::string drop_root, bool use_inotify, int settle_ms)
    : root_(fs::absolute(drop_root).lexically_normal().string()), settle_ms_(settle_ms) {
  while (root_.size() > 1 && root_.back() == '/') root_.pop_back();
  fs::create_directories(root_ + "/protect");
  fs::create_directories(root_ + "/detect");
  if (use_inotify) {
    inotify_fd_ = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
    if (inotify_fd_ < 0)
      spdlog::warn("inotify unavailable ({}); drop folders are polled", std::strerror(errno));
  }
  if (inotify_fd_ >= 0) {
    add_watch("protect");
    add_watch("detect");
    for (const auto& e : fs::directory_iterator(root_ + "/protect")) {
      std::string name = e.path().filename().string();
      if (is_valid_customer_name(name) && lstat_is(e.path().string(), S_IFDIR)) add_watch("protect/" + name);
    }
  }
}

DropWatcher::~DropWatcher() {
  if (inotify_fd_ >= 0) ::close(inotify_fd_);
}

void DropWatcher::add_watch(const std::string& dir) {
  if (inotify_fd_ < 0) return;
  for (const auto& [wd, d] : watches_)
    if (d == dir) return;
  std::uint32_t mask = IN_CLOSE_WRITE | IN_MOVED_TO | IN_CREATE | IN_MODIFY | IN_DELETE_SELF | IN_ONLYDIR |
                       IN_DONT_FOLLOW;
  int wd = ::inotify_add_watch(inotify_fd_, (root_ + "/" + dir).c_str(), mask);
  if (wd < 0) {
    spdlog::warn("cannot watch {}/{}: {}; it is polled", root_, dir, std::strerror(errno));
    return;
  }
  watches_[wd] = dir;
}

void DropWatcher::read_events(std::int64_t now_ms) {
  if (inotify_fd_ < 0) return;
  alignas(struct inotify_event) char buf[16384];
  while (true) {
    ssize_t len = ::read(inotify_fd_, buf, sizeof buf);
    if (len <= 0) break;
    for (char* p = buf; p < buf + len;) {
      auto* ev = reinterpret_cast<struct inotify_event*>(p);
      p += sizeof(struct inotify_event) + ev->len;
      if (ev->mask & IN_Q_OVERFLOW) {
        spdlog::warn("inotify queue overflow; rescanning drop folders");
        continue;  // the scan below catches everything
      }
      auto it = watches_.find(ev->wd);
      if (it == watches_.end()) continue;
      if (ev->mask & IN_IGNORED) {
        watches_.erase(it);
        continue;
      }
      if (ev->len == 0) continue;
      std::string name(ev->name);
      std::string rel = it->second + "/" + name;
      if (ev->mask & IN_ISDIR) {
        if (it->second == "protect" && (ev->mask & (IN_CREATE | IN_MOVED_TO)) && is_valid_customer_name(name) &&
            lstat_is(root_ + "/" + rel, S_IFDIR))
          add_watch(rel);
        continue;
      }
      if (ev->mask & IN_CREATE) writing_.insert(rel);
      if (ev->mask & IN_MODIFY) seen_.erase(rel);
      // Renamed into place: complete. Closed after writing: perhaps only one of several appends,
      // so it is taken once unchanged for settle_ms (a copy must not be issued from half a part).
      if (ev->mask & IN_MOVED_TO) {
        writing_.erase(rel);
        consider(rel, now_ms, true);
      } else if (ev->mask & IN_CLOSE_WRITE) {
        writing_.erase(rel);
        consider(rel, now_ms, false);
      }
    }
  }
}

void DropWatcher::consider(const std::string& rel, std::int64_t now_ms, bool closed) {
  std::string why;
  auto item = classify_drop_path(root_, rel, &why);
  if (!item) {
    seen_.erase(rel);
    return;
  }
  if (reported_.count(item->path)) return;
  if (!closed) {
    if (writing_.count(rel)) return;  // inotify saw it created and not yet closed
    struct stat st;
    if (::lstat(item->path.c_str(), &st) != 0) return;
    std::int64_t mtime = std::int64_t(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec;
    if (age_only_) {
      if (now_ms - mtime / 1000000 < settle_ms_) return;
      reported_.insert(item->path);
      ready_.push_back(*item);
      return;
    }
    auto& s = seen_[rel];
    if (s.since_ms == 0 || s.size != static_cast<std::uintmax_t>(st.st_size) || s.mtime_ns != mtime) {
      s = {static_cast<std::uintmax_t>(st.st_size), mtime, now_ms};
      if (settle_ms_ > 0) return;
    }
    std::int64_t age_ms = now_ms - mtime / 1000000;
    if (now_ms - s.since_ms < settle_ms_ || age_ms < settle_ms_) return;
  }
  seen_.erase(rel);
  reported_.insert(item->path);
  ready_.push_back(*item);
}

void DropWatcher::scan(std::int64_t now_ms) {
  std::error_code ec;
  for (const auto& area : {std::string("protect"), std::string("detect")}) {
    std::string dir = root_ + "/" + area;
    if (!lstat_is(dir, S_IFDIR)) continue;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
      std::string name = it->path().filename().string();
      if (area == "detect") {
        consider("detect/" + name, now_ms, false);
        continue;
      }
      if (!is_valid_customer_name(name) || !lstat_is(it->path().string(), S_IFDIR)) continue;
      add_watch("protect/" + name);
      std::error_code ec2;
      for (fs::directory_iterator f(it->path(), ec2), fend; !ec2 && f != fend; f.increment(ec2))
        consider("protect/" + name + "/" + f->path().filename().string(), now_ms, false);
    }
  }
}

std::vector<DropItem> DropWatcher::poll(std::int64_t now_ms) {
  read_events(now_ms);
  scan(now_ms);
  std::vector<DropItem> out;
  out.swap(ready_);
  return out;
}

int remove_stale_reason_temps(const std::string& drop_root) {
  int n = 0;
  for (const char* area : {"done", "failed"}) {
    std::error_code ec;
    fs::path dir = fs::path(drop_root) / area;
    if (!fs::is_directory(fs::symlink_status(dir))) continue;
    for (fs::recursive_directory_iterator it(dir, fs::directory_options::none, ec), end; !ec && it != end;
         it.increment(ec)) {
      std::string name = it->path().filename().string();
      if (support::is_atomic_write_temporary(name) && name.find(".json.tmp.") != std::string::npos &&
          it->is_regular_file() && !it->is_symlink()) {
        std::error_code ec2;
        if (fs::remove(it->path(), ec2)) ++n;
      }
    }
  }
  return n;
}

std::vector<DropItem> DropWatcher::scan_once(std::int64_t now_ms) {
  age_only_ = true;
  scan(now_ms);
  age_only_ = false;
  std::vector<DropItem> out;
  out.swap(ready_);
  return out;
}

void DropWatcher::forget(const std::string& path) {
  reported_.erase(path);
}

std::string DropWatcher::finish(const std::string& drop_root, const DropItem& item, bool ok,
                                const std::string& reason_json) {
  fs::path dest_dir = fs::path(drop_root) / (ok ? "done" : "failed") / fs::path(item.relative).parent_path();
  fs::create_directories(dest_dir);
  fs::path name(item.name);
  std::string stem = name.stem().string(), ext = name.extension().string();
  fs::path dest = dest_dir / item.name;
  // A reason file without its file beside it is an orphan of a crash between the two steps below;
  // it is replaced, not kept.
  for (int i = 1; fs::exists(fs::symlink_status(dest)); ++i)
    dest = dest_dir / (stem + "-" + std::to_string(i) + ext);
  write_text_atomic(dest.string() + ".json", reason_json);
  if (::rename(item.path.c_str(), dest.c_str()) != 0)
    throw std::system_error(errno, std::generic_category(), "cannot move " + item.path + " to " + dest.string());
  return dest.string();
}

}  // namespace mm::service
