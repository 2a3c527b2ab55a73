#include "service/context_cache.h"

#include <algorithm>
#include <condition_variable>
#include <exception>
#include <list>
#include <mutex>
#include <unordered_map>

namespace mm::service {

namespace {

struct Entry {
  std::string key;
  std::shared_ptr<const ResyncContext> context;  // null while building
  bool building = true;
  std::exception_ptr failed;  // the build's exception, for the requests that waited on it
  std::size_t users = 0;      // leases alive, plus the build itself and its waiters
};

}  // namespace

struct ContextCache::State {
  mutable std::mutex mutex;
  std::condition_variable built;  // an entry finished building (or failed)
  std::size_t budget = 0;
  std::list<std::shared_ptr<Entry>> lru;  // most recently used first
  std::unordered_map<std::string, std::list<std::shared_ptr<Entry>>::iterator> index;
  std::size_t builds = 0, hits = 0, evictions = 0, waiting = 0;

  std::size_t bytes_locked() const {
    std::size_t total = 0;
    for (const auto& e : lru)
      if (e->context) total += e->context->memory_bytes();
    return total;
  }

  // Least recently used first, skipping entries in use, until the held contexts fit.
  void trim_locked() {
    std::size_t total = bytes_locked();
    for (auto it = lru.end(); it != lru.begin() && total > budget;) {
      --it;
      const Entry& e = **it;
      if (e.users > 0 || !e.context) continue;
      total -= std::min(total, e.context->memory_bytes());
      index.erase(e.key);
      it = lru.erase(it);
      ++evictions;
    }
  }

  void erase_locked(const std::shared_ptr<Entry>& e) {
    auto found = index.find(e->key);
    if (found == index.end() || *found->second != e) return;
    lru.erase(found->second);
    index.erase(found);
  }

  // The context dies with the entry's last reference (the cache's or a lease's), outside the lock
  // when the lease is last: the lock guards only the bookkeeping.
  std::shared_ptr<const ResyncContext> lease(const std::shared_ptr<State>& self, const std::shared_ptr<Entry>& e) {
    std::weak_ptr<State> weak = self;
    return std::shared_ptr<const ResyncContext>(e->context.get(), [weak, e](const ResyncContext*) {
      if (auto s = weak.lock()) {
        std::lock_guard lock(s->mutex);
        --e->users;
        s->trim_locked();
      }
    });
  }
};

ContextCache::ContextCache(std::size_t budget_bytes) : state_(std::make_shared<State>()) {
  state_->budget = budget_bytes;
}

ContextCache::~ContextCache() = default;

void ContextCache::set_budget(std::size_t budget_bytes) {
  std::lock_guard lock(state_->mutex);
  state_->budget = budget_bytes;
  state_->trim_locked();
}

std::shared_ptr<const ResyncContext> ContextCache::get(const std::string& key,
                                                        const std::function<ResyncContext()>& build) {
  State& s = *state_;
  std::unique_lock lock(s.mutex);
  if (auto found = s.index.find(key); found != s.index.end()) {
    std::shared_ptr<Entry> e = *found->second;
    s.lru.splice(s.lru.begin(), s.lru, found->second);
    ++e->users;
    if (e->building) {
      ++s.waiting;
      s.built.wait(lock, [&] { return !e->building; });
      --s.waiting;
    }
    if (!e->context) {  // the build failed; the builder took the entry out of the cache
      --e->users;
      std::rethrow_exception(e->failed);
    }
    ++s.hits;
    s.trim_locked();
    return s.lease(state_, e);
  }
  auto e = std::make_shared<Entry>();
  e->key = key;
  e->users = 1;
  s.lru.push_front(e);
  s.index[key] = s.lru.begin();
  ++s.builds;
  lock.unlock();
  // Built without the lock: other keys stay available, and requests for this one wait above.
  std::shared_ptr<const ResyncContext> context;
  std::exception_ptr failed;
  try {
    context = std::make_shared<const ResyncContext>(build());
  } catch (...) {
    failed = std::current_exception();
  }
  lock.lock();
  e->building = false;
  e->context = context;
  e->failed = failed;
  if (!context) {
    --e->users;
    s.erase_locked(e);
  }
  s.built.notify_all();
  if (failed) std::rethrow_exception(failed);
  s.trim_locked();
  return s.lease(state_, e);
}

ContextCache::Stats ContextCache::stats() const {
  const State& s = *state_;
  std::lock_guard lock(s.mutex);
  Stats st;
  st.entries = s.lru.size();
  for (const auto& e : s.lru) st.in_use += e->users > 0 ? 1 : 0;
  st.bytes = s.bytes_locked();
  st.budget = s.budget;
  st.builds = s.builds;
  st.hits = s.hits;
  st.evictions = s.evictions;
  st.waiting = s.waiting;
  return st;
}

}  // namespace mm::service
