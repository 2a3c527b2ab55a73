#include "codec/connectivity.h"

#include <algorithm>
#include <deque>
#include <stdexcept>
#include <unordered_set>

#include "codec/bytes.h"

namespace mm::codec_detail {
namespace {

// Neighbour lists in the order edges become known, shared by encoder and decoder so ranks agree.
// Edge membership uses a hash set, so hostile high-degree vertices cannot make this quadratic.
class Neighbours {
 public:
  explicit Neighbours(int n) : lists_(static_cast<std::size_t>(n)) {}
  void add_face(const std::vector<int>& f) {
    for (std::size_t k = 0; k < f.size(); ++k) {
      const int u = f[k], v = f[(k + 1) % f.size()];
      const std::uint64_t key = (static_cast<std::uint64_t>(std::min(u, v)) << 32) |
                                static_cast<std::uint32_t>(std::max(u, v));
      if (known_.insert(key).second) {
        lists_[u].push_back(v);
        lists_[v].push_back(u);
      }
      placed_.insert((static_cast<std::uint64_t>(static_cast<std::uint32_t>(u)) << 32) |
                     static_cast<std::uint32_t>(v));
    }
  }
  // Whether a placed face holds the directed edge (u, v).
  bool placed(int u, int v) const {
    return placed_.count((static_cast<std::uint64_t>(static_cast<std::uint32_t>(u)) << 32) |
                         static_cast<std::uint32_t>(v)) > 0;
  }
  const std::vector<int>& of(int v) const { return lists_[v]; }
  bool adjacent(int u, int v) const {
    return known_.count((static_cast<std::uint64_t>(std::min(u, v)) << 32) |
                        static_cast<std::uint32_t>(std::max(u, v))) > 0;
  }

 private:
  std::vector<std::vector<int>> lists_;
  std::unordered_set<std::uint64_t> known_;
  std::unordered_set<std::uint64_t> placed_;
};

using Gate = std::pair<int, int>;
struct QueuedGate {
  int a, b, from_size;
};

void push_gates(std::deque<QueuedGate>& gates, const std::vector<int>& f, std::size_t first) {
  for (std::size_t k = first; k < f.size(); ++k)
    gates.push_back({f[k], f[(k + 1) % f.size()], static_cast<int>(f.size())});
}

// Version 3 escapes: known vertices two edges from a gate vertex (neighbours of the anchor's,
// then of the other's, most recent first), excluding the gate vertices and their own
// neighbours (those have ranks). A face that meets the traversal front elsewhere mostly closes
// onto such a vertex. Bounded (kRingEntries entries, kRingScan list entries read) so hostile
// high-degree vertices cannot make it expensive.
constexpr std::size_t kRingEntries = 32, kRingScan = 256;
std::vector<int> two_ring(const Neighbours& nb, int anchor, int other) {
  std::vector<int> ring;
  std::size_t scanned = 0;
  for (int x : {anchor, other})
    for (auto u = nb.of(x).rbegin(); u != nb.of(x).rend(); ++u) {
      if (++scanned > kRingScan) return ring;
      for (auto y = nb.of(*u).rbegin(); y != nb.of(*u).rend(); ++y) {
        if (++scanned > kRingScan || ring.size() >= kRingEntries) return ring;
        if (*y == anchor || *y == other || nb.adjacent(*y, anchor) || nb.adjacent(*y, other)) continue;
        if (std::find(ring.begin(), ring.end(), *y) == ring.end()) ring.push_back(*y);
      }
    }
  return ring;
}

// Hints look at the last kHintScan entries of each list only, so a decision costs O(1) however
// large a (hostile) vertex's degree. A hint found there has a rank below 2 + 2 kHintScan + 1,
// and an entry deeper than kHintScan in the other list would rank higher, so searching the last
// kHintScan entries of both lists gives the vertex's rank exactly.
constexpr std::size_t kHintScan = 64;

// Rank of a vertex v found among the last kHintScan entries of a gate vertex's list, under the
// rank rules (the smaller of its ranks in the two lists).
std::uint64_t rank_of(const Neighbours& nb, int v, int anchor, int other) {
  auto position = [&](const std::vector<int>& list) -> std::int64_t {
    for (std::size_t k = 0; k < list.size() && k < kHintScan; ++k)
      if (list[list.size() - 1 - k] == v) return static_cast<std::int64_t>(k);
    return -1;
  };
  const std::int64_t ka = position(nb.of(anchor)), kb = position(nb.of(other));
  std::uint64_t r = 0;
  if (ka >= 0) r = 2 + 2 * static_cast<std::uint64_t>(ka);
  if (kb >= 0) {
    const std::uint64_t r2 = 3 + 2 * static_cast<std::uint64_t>(kb);
    if (r == 0 || r2 < r) r = r2;
  }
  return r;
}

// Context for coding the vertex across gate (a, b): `second` is the quad's last vertex (anchor
// b); `triangle` says the new face is (b, a, x). See RankContext::hint.
RankContext rank_context(const Neighbours& nb, int anchor, int other, int second, bool triangle,
                         std::int64_t fresh, int num_vertices) {
  RankContext ctx;
  ctx.fresh_possible = fresh < num_vertices;
  ctx.anchor_degree = static_cast<int>(nb.of(anchor).size());
  ctx.other_degree = static_cast<int>(nb.of(other).size());
  ctx.second = second;
  // x first (edges (a, x) and, for a triangle, (x, b) are new): open if (x, a) / (b, x) is
  // placed and its reverse is not. y second (edge (y, b) new, b the anchor): open if (b, y) is.
  auto open_at_anchor = [&](int x) {
    return second ? nb.placed(anchor, x) && !nb.placed(x, anchor) : nb.placed(x, anchor) && !nb.placed(anchor, x);
  };
  auto open_at_other = [&](int x) { return triangle && nb.placed(other, x) && !nb.placed(x, other); };
  int first_anchor = -1, first_other = -1;
  const auto& la = nb.of(anchor);
  for (std::size_t k = 0; k < la.size() && k < kHintScan && first_anchor < 0; ++k)
    if (open_at_anchor(la[la.size() - 1 - k])) first_anchor = la[la.size() - 1 - k];
  const auto& lb = nb.of(other);
  if (triangle)
    for (std::size_t k = 0; k < lb.size() && k < kHintScan && first_other < 0; ++k)
      if (open_at_other(lb[lb.size() - 1 - k])) first_other = lb[lb.size() - 1 - k];
  if (first_anchor >= 0) ctx.hint_anchor = rank_of(nb, first_anchor, anchor, other);
  if (first_other >= 0) ctx.hint_other = rank_of(nb, first_other, anchor, other);
  if (first_anchor >= 0 && first_other >= 0) ctx.hint_kind = first_anchor == first_other ? 1 : 2;
  else if (first_anchor >= 0) ctx.hint_kind = 3;
  else if (first_other >= 0) ctx.hint_kind = 4;
  return ctx;
}

}  // namespace

void encode_faces(const std::vector<std::vector<int>>& faces, int num_vertices,
                  std::vector<std::vector<int>>* traversal_order, FaceSink& sink) {
  std::vector<std::vector<int>> canon = faces;
  for (auto& f : canon) std::rotate(f.begin(), std::min_element(f.begin(), f.end()), f.end());
  std::sort(canon.begin(), canon.end());
  // Directed edge -> faces holding it, in canonical order: (edge, face) rows sorted, so a
  // gate's faces are one run (a map of vectors cost a sixth more instructions per traversal,
  // which the stream search runs for 64 numberings of each chosen polyhedron).
  std::vector<std::pair<Gate, std::size_t>> holder;
  for (std::size_t i = 0; i < canon.size(); ++i)
    for (std::size_t k = 0; k < canon[i].size(); ++k)
      holder.push_back({{canon[i][k], canon[i][(k + 1) % canon[i].size()]}, i});
  std::sort(holder.begin(), holder.end());

  Neighbours nb(num_vertices);
  std::vector<char> visited(canon.size(), 0);
  std::size_t done = 0, next_start = 0;
  std::deque<QueuedGate> gates;
  if (traversal_order) traversal_order->clear();
  std::vector<char> seen(static_cast<std::size_t>(num_vertices), 0);
  std::int64_t fresh = 0;
  auto plain = [&](int v) {
    sink.index(zigzag(static_cast<std::int64_t>(v) - fresh));
    if (!seen[v]) seen[v] = 1, ++fresh;
  };
  auto note = [&](int v) {
    if (!seen[v]) seen[v] = 1, ++fresh;
  };
  auto code_vertex = [&](int v, int anchor, int other, int second, bool triangle) {
    const auto& list = nb.of(anchor);
    const RankContext ctx = sink.wants_contexts()
                                ? rank_context(nb, anchor, other, second, triangle, fresh, num_vertices)
                                : RankContext{};
    // 0: the next unseen number; 1: escape; 2 + 2k: the anchor's k-th most recent neighbour;
    // 3 + 2k: the other gate vertex's (a face closing a fan on either side mostly meets the
    // last one known).
    if (v == fresh && !seen[v]) {
      sink.rank(0, ctx);
      note(v);
      return;
    }
    const auto& list2 = nb.of(other);
    const auto it = std::find(list.rbegin(), list.rend(), v);
    const auto it2 = std::find(list2.rbegin(), list2.rend(), v);
    std::uint64_t r = 0;
    if (it != list.rend()) r = 2 + 2 * static_cast<std::uint64_t>(it - list.rbegin());
    if (it2 != list2.rend()) {
      const std::uint64_t r2 = 3 + 2 * static_cast<std::uint64_t>(it2 - list2.rbegin());
      if (r == 0 || r2 < r) r = r2;
    }
    if (r > 0) {
      sink.rank(r, ctx);
      note(v);
      return;
    }
    // Escape: position in the two-ring, else past it the index relative to `fresh`.
    sink.rank(1, ctx);
    const auto ring = two_ring(nb, anchor, other);
    const auto at = std::find(ring.begin(), ring.end(), v);
    sink.escape(at != ring.end() ? static_cast<std::uint64_t>(at - ring.begin())
                                 : ring.size() + zigzag(static_cast<std::int64_t>(v) - fresh));
    note(v);
  };
  int previous = 1;
  while (done < canon.size()) {
    if (gates.empty()) {
      while (visited[next_start]) ++next_start;
      const auto& f = canon[next_start];
      visited[next_start] = 1;
      ++done;
      sink.start(static_cast<int>(f.size()));
      for (int v : f) plain(v);
      nb.add_face(f);
      push_gates(gates, f, 0);
      if (traversal_order) traversal_order->push_back(f);
      continue;
    }
    const QueuedGate g = gates.front();
    const int a = g.a, b = g.b;
    gates.pop_front();
    // A gate whose far side is already held by a placed face costs nothing.
    if (nb.placed(b, a)) continue;
    std::size_t across = canon.size();
    for (auto h = std::lower_bound(holder.begin(), holder.end(), std::make_pair(Gate{b, a}, std::size_t{0}));
         h != holder.end() && h->first == Gate{b, a}; ++h)
      if (!visited[h->second]) {
        across = h->second;
        break;
      }
    const GateContext gctx{g.from_size, previous};
    if (across == canon.size()) {
      sink.symbol(0, gctx);
      previous = 0;
      continue;
    }
    std::vector<int> f = canon[across];
    visited[across] = 1;
    ++done;
    std::rotate(f.begin(), std::find(f.begin(), f.end(), b), f.end());  // f = (b, a, x[, y])
    previous = static_cast<int>(f.size() - 2);
    sink.symbol(previous, gctx);
    code_vertex(f[2], a, b, 0, f.size() == 3);
    if (f.size() == 4) code_vertex(f[3], b, a, 1, false);
    nb.add_face(f);
    push_gates(gates, f, 1);
    if (traversal_order) traversal_order->push_back(f);
  }
}

std::vector<std::vector<int>> decode_faces(FaceSource& source, std::uint32_t num_faces,
                                           int num_vertices) {
  const std::uint64_t max_index = num_vertices > 0 ? static_cast<std::uint64_t>(num_vertices) - 1 : 0;
  std::vector<char> seen(static_cast<std::size_t>(num_vertices), 0);
  std::int64_t fresh = 0;
  auto note = [&](int v) {
    if (!seen[v]) seen[v] = 1, ++fresh;
  };
  auto plain = [&]() {
    if (num_vertices == 0) source.fail("a face refers to a vertex but the mesh has none");
    const std::int64_t v = fresh + unzigzag(source.index(2 * max_index + 1));
    if (v < 0 || v > static_cast<std::int64_t>(max_index))
      source.fail("vertex index " + std::to_string(v) + " outside [0, " + std::to_string(max_index) + "]");
    note(static_cast<int>(v));
    return static_cast<int>(v);
  };
  Neighbours nb(num_vertices);
  auto coded_vertex = [&](int anchor, int other, int second, bool triangle) {
    const auto& list = nb.of(anchor);
    RankContext ctx = rank_context(nb, anchor, other, second, triangle, fresh, num_vertices);
    ctx.fresh_possible = fresh < num_vertices;
    const std::uint64_t r = source.rank(ctx);
    if (r == 0) {
      if (fresh >= num_vertices) source.fail("a new vertex but all " + std::to_string(num_vertices) + " are used");
      const int v = static_cast<int>(fresh);
      note(v);
      return v;
    }
    if (r == 1) {
      if (num_vertices == 0) source.fail("a face refers to a vertex but the mesh has none");
      const auto ring = two_ring(nb, anchor, other);
      const std::uint64_t code = source.escape(ring.size() + 2 * max_index + 1);
      std::int64_t v;
      if (code < ring.size()) {
        v = ring[code];
      } else {
        v = fresh + unzigzag(code - ring.size());
        if (v < 0 || v > static_cast<std::int64_t>(max_index))
          source.fail("vertex index " + std::to_string(v) + " outside [0, " + std::to_string(max_index) + "]");
      }
      note(static_cast<int>(v));
      return static_cast<int>(v);
    }
    const auto& from = r % 2 == 0 ? list : nb.of(other);
    const std::uint64_t k = (r - 2) / 2;
    if (k >= from.size())
      source.fail("neighbour rank " + std::to_string(r) + " but vertex " +
                  std::to_string(r % 2 == 0 ? anchor : other) + " has " + std::to_string(from.size()) +
                  " known neighbours");
    const int v = from[from.size() - 1 - k];
    note(v);
    return v;
  };
  auto check_distinct = [&](const std::vector<int>& f, std::size_t index) {
    for (std::size_t i = 0; i < f.size(); ++i)
      for (std::size_t j = 0; j < i; ++j)
        if (f[i] == f[j]) source.fail("face " + std::to_string(index) + " repeats a vertex");
  };

  std::vector<std::vector<int>> faces;
  faces.reserve(num_faces);  // bounded by the payload size check in the stream header
  std::deque<QueuedGate> gates;
  int previous = 1;
  while (faces.size() < num_faces) {
    if (gates.empty()) {
      const int s = source.start();
      if (s != 3 && s != 4)
        source.fail("expected a component start (3 or 4), found " + std::to_string(s));
      std::vector<int> f(static_cast<std::size_t>(s));
      for (int& v : f) v = plain();
      check_distinct(f, faces.size());
      nb.add_face(f);
      push_gates(gates, f, 0);
      faces.push_back(std::move(f));
      continue;
    }
    const QueuedGate g = gates.front();
    const int a = g.a, b = g.b;
    gates.pop_front();
    if (nb.placed(b, a)) continue;
    const int s = source.symbol(GateContext{g.from_size, previous});
    if (s < 0 || s > 2) source.fail("gate symbol " + std::to_string(s) + " is not 0, 1 or 2");
    previous = s;
    if (s == 0) continue;
    std::vector<int> f = {b, a};
    f.push_back(coded_vertex(a, b, 0, s == 1));
    if (s == 2) f.push_back(coded_vertex(b, a, 1, false));
    check_distinct(f, faces.size());
    nb.add_face(f);
    push_gates(gates, f, 1);
    faces.push_back(std::move(f));
  }
  return faces;
}

}  // namespace mm::codec_detail
