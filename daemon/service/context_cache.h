// Resynchronisation contexts shared by every worker of a process, held to a memory budget.
//
// One context per key (a polyhedron's content address): the first worker to ask builds it, a
// worker asking while it is being built waits for that build instead of starting its own. A
// context is handed out as a shared_ptr (a lease); while any lease is alive the context is in
// use and is never evicted. Contexts grow while they are used (registration builds subdivision
// levels on first use), so the budget is checked whenever a lease ends and whenever a context is
// asked for: least recently used contexts that are not in use are evicted until the contexts
// held (in use or not) fit in the budget. Contexts in use alone may exceed it (a worker needs
// its context), so the memory held is at most max(budget, contexts in use), and contexts in use
// are at most one per worker in the detect handler. A budget of 0 keeps nothing between uses.
#pragma once
#include <cstddef>
#include <functional>
#include <memory>
#include <string>

#include "registration/resynchronize.h"

namespace mm::service {

class ContextCache {
 public:
  explicit ContextCache(std::size_t budget_bytes);
  ~ContextCache();
  ContextCache(const ContextCache&) = delete;
  ContextCache& operator=(const ContextCache&) = delete;

  // Takes effect at once (evicts what no longer fits). The daemon sets it from the
  // configuration before each detect job, so a reload applies to the next job.
  void set_budget(std::size_t budget_bytes);

  // The context for `key`, built by `build` if the cache has none. The lease keeps it alive and
  // marks it in use until released (it may outlive the cache). If `build` throws, every waiter
  // gets that exception and the next request builds again.
  std::shared_ptr<const ResyncContext> get(const std::string& key, const std::function<ResyncContext()>& build);

  struct Stats {
    std::size_t entries = 0;  // contexts held, built or being built
    std::size_t in_use = 0;   // of them, with a lease alive (or a build running)
    std::size_t bytes = 0;    // ResyncContext::memory_bytes() summed over the built ones
    std::size_t budget = 0;
    std::size_t builds = 0, hits = 0, evictions = 0;  // since construction
    std::size_t waiting = 0;  // requests waiting now for a build another request started
  };
  Stats stats() const;

 private:
  struct State;
  std::shared_ptr<State> state_;  // shared with the leases, which may outlive the cache
};

}  // namespace mm::service
