// The detect handler's shared context cache: one build per key even when requests race, the
// memory budget (contexts grow while in use), least-recently-used eviction that never takes a
// context in use, failed builds retried, leases that outlive the cache.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <future>
#include <map>
#include <mutex>
#include <thread>

#include "service/context_cache.h"

namespace mm::service {
namespace {

// A small closed control mesh (a cube of quads) with a crease: its levels are a few kB to a few
// hundred kB, built in milliseconds.
Mesh cube() {
  Mesh m;
  m.points.resize(8, 3);
  m.points << -1, -1, -1, 1, -1, -1, 1, 1, -1, -1, 1, -1, -1, -1, 1, 1, -1, 1, 1, 1, 1, -1, 1, 1;
  m.faces = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
  m.creases = {{0, 1}, {1, 2}, {2, 3}, {0, 3}};
  return m;
}

// Builds contexts of the cube, counting the builds per key.
struct Builder {
  std::map<std::string, int> count;
  std::mutex mutex;
  std::function<ResyncContext()> operator()(const std::string& key) {
    return [this, key] {
      {
        std::lock_guard lock(mutex);
        ++count[key];
      }
      return ResyncContext(cube(), 3);
    };
  }
  int builds(const std::string& key) {
    std::lock_guard lock(mutex);
    return count[key];
  }
};

// What a context takes once a suspect has needed its level 3 (levels 0..3 built).
std::size_t used_size() {
  ResyncContext c(cube(), 3);
  c.refined_points(3);
  return c.memory_bytes();
}

// Uses a context as a detection does: its top level gets built.
void use(const std::shared_ptr<const ResyncContext>& c) { ASSERT_GT(c->refined_points(3).rows(), 0); }

template <class Pred>
bool eventually(Pred pred) {
  for (int i = 0; i < 2000; ++i) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

}  // namespace

TEST(ContextCache, OneContextPerKeyReusedAcrossRequests) {
  ContextCache cache(std::size_t{1} << 30);
  Builder b;
  const ResyncContext* first = nullptr;
  {
    auto c = cache.get("a", b("a"));
    first = c.get();
    use(c);
  }
  auto again = cache.get("a", b("a"));
  EXPECT_EQ(again.get(), first);
  EXPECT_EQ(b.builds("a"), 1);
  const auto st = cache.stats();
  EXPECT_EQ(st.entries, 1u);
  EXPECT_EQ(st.in_use, 1u);
  EXPECT_EQ(st.builds, 1u);
  EXPECT_EQ(st.hits, 1u);
  EXPECT_EQ(st.bytes, again->memory_bytes());
}

TEST(ContextCache, BudgetEvictsLeastRecentlyUsedOnceContextsGrow) {
  const std::size_t size = used_size();
  ResyncContext fresh(cube(), 3);
  ASSERT_LT(fresh.memory_bytes() * 4, size);  // contexts grow while used: the budget sees that
  ContextCache cache(size * 5 / 2);            // room for two used contexts
  Builder b;
  for (const char* k : {"a", "b", "c"}) {
    use(cache.get(k, b(k)));
    EXPECT_LE(cache.stats().bytes, cache.stats().budget) << k;
  }
  EXPECT_EQ(cache.stats().entries, 2u);
  EXPECT_EQ(cache.stats().evictions, 1u);
  use(cache.get("b", b("b")));  // b, c kept (a was the least recently used); now c is
  use(cache.get("c", b("c")));
  use(cache.get("b", b("b")));
  EXPECT_EQ(b.builds("b"), 1);
  EXPECT_EQ(b.builds("c"), 1);
  use(cache.get("a", b("a")));  // rebuilt; evicts c, the least recently used
  EXPECT_EQ(b.builds("a"), 2);
  use(cache.get("b", b("b")));
  EXPECT_EQ(b.builds("b"), 1);
  use(cache.get("c", b("c")));
  EXPECT_EQ(b.builds("c"), 2);
  EXPECT_LE(cache.stats().bytes, cache.stats().budget);
  EXPECT_EQ(cache.stats().entries, 2u);

  // A smaller budget applies at once; 0 keeps nothing that is not in use.
  cache.set_budget(size * 3 / 2);
  EXPECT_EQ(cache.stats().entries, 1u);
  cache.set_budget(0);
  EXPECT_EQ(cache.stats().entries, 0u);
  EXPECT_EQ(cache.stats().bytes, 0u);
}

TEST(ContextCache, ContextsInUseSurviveEviction) {
  ContextCache cache(0);
  Builder b;
  auto a = cache.get("a", b("a"));
  use(a);
  {
    auto other = cache.get("b", b("b"));
    use(other);
    EXPECT_EQ(cache.stats().entries, 2u);  // both in use: over budget, nothing evictable
    EXPECT_EQ(cache.stats().in_use, 2u);
  }
  EXPECT_EQ(cache.stats().entries, 1u);  // b went when its lease ended, a stays while used
  auto a2 = cache.get("a", b("a"));
  EXPECT_EQ(a2.get(), a.get());
  EXPECT_EQ(b.builds("a"), 1);
  a.reset();
  EXPECT_EQ(cache.stats().entries, 1u);  // a2 still holds it
  EXPECT_EQ(a2->refined_points(3).rows(), ResyncContext(cube(), 3).vertex_count(3));
  a2.reset();
  EXPECT_EQ(cache.stats().entries, 0u);
}

TEST(ContextCache, ConcurrentRequestsForOneKeyBuildOnce) {
  ContextCache cache(std::size_t{1} << 30);
  std::atomic<int> builds{0};
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  auto slow = [&] {
    ++builds;
    released.wait();  // holds the build until the second request is waiting for it
    return ResyncContext(cube(), 3);
  };
  auto first = std::async(std::launch::async, [&] { return cache.get("k", slow); });
  ASSERT_TRUE(eventually([&] { return builds.load() == 1; }));
  auto second = std::async(std::launch::async, [&] { return cache.get("k", slow); });
  ASSERT_TRUE(eventually([&] { return cache.stats().waiting == 1; }));
  // Another key is not held up by the build in progress.
  Builder b;
  auto other = std::async(std::launch::async, [&] { return cache.get("other", b("other")); });
  ASSERT_EQ(other.wait_for(std::chrono::seconds(30)), std::future_status::ready);
  EXPECT_NE(other.get(), nullptr);
  release.set_value();
  auto c1 = first.get();
  auto c2 = second.get();
  EXPECT_EQ(c1.get(), c2.get());
  EXPECT_EQ(builds.load(), 1);
  EXPECT_EQ(cache.stats().builds, 2u);  // "k" and "other"
  EXPECT_EQ(cache.stats().hits, 1u);
}

TEST(ContextCache, FailedBuildReachesEveryWaiterAndIsRetried) {
  ContextCache cache(std::size_t{1} << 30);
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  std::atomic<int> calls{0};
  auto failing = [&]() -> ResyncContext {
    ++calls;
    released.wait();
    throw InputError("control polyhedron", "unusable");
  };
  auto first = std::async(std::launch::async, [&] { return cache.get("k", failing); });
  ASSERT_TRUE(eventually([&] { return calls.load() == 1; }));
  auto second = std::async(std::launch::async, [&] { return cache.get("k", failing); });
  ASSERT_TRUE(eventually([&] { return cache.stats().waiting == 1; }));
  release.set_value();
  EXPECT_THROW(first.get(), InputError);
  EXPECT_THROW(second.get(), InputError);
  EXPECT_EQ(calls.load(), 1);
  EXPECT_EQ(cache.stats().entries, 0u);
  Builder b;
  EXPECT_NE(cache.get("k", b("k")), nullptr);  // built afresh
  EXPECT_EQ(b.builds("k"), 1);
}

TEST(ContextCache, LeaseOutlivesTheCache) {
  std::shared_ptr<const ResyncContext> lease;
  {
    ContextCache cache(std::size_t{1} << 30);
    Builder b;
    lease = cache.get("a", b("a"));
  }
  use(lease);
  lease.reset();  // releases without a cache to report to
}

}  // namespace mm::service
