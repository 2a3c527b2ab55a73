#include "codec/connectivity.h"

#include <algorithm>
#include <deque>
#include <map>
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

 private:
  std::vector<std::vector<int>> lists_;
  std::unordered_set<std::uint64_t> known_;
  std::unordered_set<std::uint64_t> placed_;
};

using Gate = std::pair<int, int>;

void push_gates(std::deque<Gate>& gates, const std::vector<int>& f, std::size_t first) {
  for (std::size_t k = first; k < f.size(); ++k) gates.emplace_back(f[k], f[(k + 1) % f.size()]);
}

}  // namespace

ConnectivityStreams encode_faces(const std::vector<std::vector<int>>& faces, int num_vertices,
                                 std::vector<std::vector<int>>* traversal_order, int version) {
  const bool relative_indices = version >= 2;
  std::vector<std::vector<int>> canon = faces;
  for (auto& f : canon) std::rotate(f.begin(), std::min_element(f.begin(), f.end()), f.end());
  std::sort(canon.begin(), canon.end());
  // Directed edge -> faces holding it, in canonical order.
  std::map<Gate, std::vector<std::size_t>> holder;
  for (std::size_t i = 0; i < canon.size(); ++i)
    for (std::size_t k = 0; k < canon[i].size(); ++k)
      holder[{canon[i][k], canon[i][(k + 1) % canon[i].size()]}].push_back(i);

  Writer symbols, ranks, vertices;
  Neighbours nb(num_vertices);
  std::vector<char> visited(canon.size(), 0);
  std::size_t done = 0, next_start = 0;
  std::deque<Gate> gates;
  if (traversal_order) traversal_order->clear();
  std::vector<char> seen(static_cast<std::size_t>(num_vertices), 0);
  std::int64_t fresh = 0;
  auto plain = [&](int v) {
    if (relative_indices) {
      vertices.varint(zigzag(static_cast<std::int64_t>(v) - fresh));
      if (!seen[v]) seen[v] = 1, ++fresh;
    } else {
      vertices.varint(static_cast<std::uint64_t>(v));
    }
  };
  auto note = [&](int v) {
    if (relative_indices && !seen[v]) seen[v] = 1, ++fresh;
  };
  auto code_vertex = [&](int v, int anchor, int other) {
    const auto& list = nb.of(anchor);
    if (relative_indices) {
      // 0: the next unseen number; 1: escape to the index stream; 2 + 2k: the anchor's k-th
      // most recent neighbour; 3 + 2k: the other gate vertex's (a face closing a fan on either
      // side mostly meets the last one known).
      if (v == fresh && !seen[v]) {
        ranks.varint(0);
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
        ranks.varint(r);
        note(v);
      } else {
        ranks.varint(1);
        plain(v);
      }
      return;
    }
    const auto it = std::find(list.begin(), list.end(), v);
    if (it != list.end()) {
      ranks.varint(static_cast<std::uint64_t>(it - list.begin()) + 1);
      note(v);
    } else {
      ranks.varint(0);
      plain(v);
    }
  };
  while (done < canon.size()) {
    if (gates.empty()) {
      while (visited[next_start]) ++next_start;
      const auto& f = canon[next_start];
      visited[next_start] = 1;
      ++done;
      symbols.u8(static_cast<std::uint8_t>(f.size()));
      for (int v : f) plain(v);
      nb.add_face(f);
      push_gates(gates, f, 0);
      if (traversal_order) traversal_order->push_back(f);
      continue;
    }
    const auto [a, b] = gates.front();
    gates.pop_front();
    // Version 2: a gate whose far side is already held by a placed face costs nothing.
    if (relative_indices && nb.placed(b, a)) continue;
    std::size_t across = canon.size();
    const auto h = holder.find({b, a});
    if (h != holder.end())
      for (std::size_t i : h->second)
        if (!visited[i]) {
          across = i;
          break;
        }
    if (across == canon.size()) {
      symbols.u8(0);
      continue;
    }
    std::vector<int> f = canon[across];
    visited[across] = 1;
    ++done;
    std::rotate(f.begin(), std::find(f.begin(), f.end(), b), f.end());  // f = (b, a, x[, y])
    symbols.u8(static_cast<std::uint8_t>(f.size() - 2));
    code_vertex(f[2], a, b);
    if (f.size() == 4) code_vertex(f[3], b, a);
    nb.add_face(f);
    push_gates(gates, f, 1);
    if (traversal_order) traversal_order->push_back(f);
  }
  return {std::move(symbols.bytes), std::move(ranks.bytes), std::move(vertices.bytes)};
}

std::vector<std::vector<int>> decode_faces(const std::uint8_t* symbols_data, std::size_t symbols_size,
                                           const std::uint8_t* ranks_data, std::size_t ranks_size,
                                           const std::uint8_t* vertices_data, std::size_t vertices_size,
                                           std::uint32_t num_faces, int num_vertices,
                                           int version, const std::string& source) {
  const bool relative_indices = version >= 2;
  Reader symbols(symbols_data, symbols_size, source, "face symbols");
  Reader ranks(ranks_data, ranks_size, source, "face vertex ranks");
  Reader vertices(vertices_data, vertices_size, source, "face vertex indices");
  const std::uint64_t max_index = num_vertices > 0 ? static_cast<std::uint64_t>(num_vertices) - 1 : 0;
  std::vector<char> seen(static_cast<std::size_t>(num_vertices), 0);
  std::int64_t fresh = 0;
  auto note = [&](int v) {
    if (relative_indices && !seen[v]) seen[v] = 1, ++fresh;
  };
  auto plain = [&]() {
    if (num_vertices == 0) vertices.fail("a face refers to a vertex but the mesh has none");
    if (!relative_indices) return static_cast<int>(vertices.varint("vertex index", max_index));
    const std::int64_t v = fresh + unzigzag(vertices.varint("vertex index offset", 2 * max_index + 1));
    if (v < 0 || v > static_cast<std::int64_t>(max_index))
      vertices.fail("vertex index " + std::to_string(v) + " outside [0, " + std::to_string(max_index) + "]");
    note(static_cast<int>(v));
    return static_cast<int>(v);
  };
  Neighbours nb(num_vertices);
  auto coded_vertex = [&](int anchor, int other) {
    const std::uint64_t r = ranks.varint("neighbour rank", 0xFFFFFFFFull);
    const auto& list = nb.of(anchor);
    if (relative_indices) {
      if (r == 0) {
        if (fresh >= num_vertices) ranks.fail("a new vertex but all " + std::to_string(num_vertices) + " are used");
        const int v = static_cast<int>(fresh);
        note(v);
        return v;
      }
      if (r == 1) return plain();
      const auto& from = r % 2 == 0 ? list : nb.of(other);
      const std::uint64_t k = (r - 2) / 2;
      if (k >= from.size())
        ranks.fail("neighbour rank " + std::to_string(r) + " but vertex " +
                   std::to_string(r % 2 == 0 ? anchor : other) + " has " + std::to_string(from.size()) +
                   " known neighbours");
      const int v = from[from.size() - 1 - k];
      note(v);
      return v;
    }
    if (r == 0) return plain();
    if (r > list.size())
      ranks.fail("neighbour rank " + std::to_string(r) + " but vertex " + std::to_string(anchor) +
                 " has " + std::to_string(list.size()) + " known neighbours");
    note(list[r - 1]);
    return list[r - 1];
  };
  auto check_distinct = [&](const std::vector<int>& f, std::size_t index) {
    for (std::size_t i = 0; i < f.size(); ++i)
      for (std::size_t j = 0; j < i; ++j)
        if (f[i] == f[j]) symbols.fail("face " + std::to_string(index) + " repeats a vertex");
  };

  std::vector<std::vector<int>> faces;
  faces.reserve(num_faces);  // bounded by the payload size check in the stream header
  std::deque<Gate> gates;
  while (faces.size() < num_faces) {
    if (gates.empty()) {
      const std::uint8_t s = symbols.u8("component start");
      if (s != 3 && s != 4)
        symbols.fail("expected a component start (3 or 4), found " + std::to_string(s));
      std::vector<int> f(s);
      for (int& v : f) v = plain();
      check_distinct(f, faces.size());
      nb.add_face(f);
      push_gates(gates, f, 0);
      faces.push_back(std::move(f));
      continue;
    }
    const auto [a, b] = gates.front();
    gates.pop_front();
    if (relative_indices && nb.placed(b, a)) continue;
    const std::uint8_t s = symbols.u8("gate symbol");
    if (s == 0) continue;
    if (s > 2) symbols.fail("gate symbol " + std::to_string(s) + " is not 0, 1 or 2");
    std::vector<int> f = {b, a};
    f.push_back(coded_vertex(a, b));
    if (s == 2) f.push_back(coded_vertex(b, a));
    check_distinct(f, faces.size());
    nb.add_face(f);
    push_gates(gates, f, 1);
    faces.push_back(std::move(f));
  }
  if (symbols.remaining() || ranks.remaining() || vertices.remaining())
    symbols.fail("unexpected trailing bytes in the face streams");
  return faces;
}

}  // namespace mm::codec_detail
