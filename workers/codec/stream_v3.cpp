#include "codec/stream_v3.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include "codec/bytes.h"
#include "codec/connectivity.h"
#include "codec/prediction.h"
#include "codec/range_coder.h"
#include "codec/stream_body_models.h"
#include "codec/stream_detail.h"

namespace mm::codec_detail {
namespace {

// ---------------------------------------------------------------------------------------------
// Coordinates: predicted in vertex order from earlier vertices, all three axes of a vertex
// together, residuals as zero flag, sign and Exp-Golomb magnitude with models per prediction kind.

// kPrevious: the previous vertex's value, for scan-ordered meshes; the others use the mesh neighbours.
enum CoordPrediction : int { kParallelogramFirst = 0, kNeighboursFirst = 1, kBlend = 2, kPrevious = 3 };

// Per vertex: the parallelograms (u, v, c) predicting it as u + v - c from vertices stored
// before it: every triangle (w, u, v) whose edge (v, u) is held by a triangle (v, u, c) (the
// first in face order), and every quad (w, u, c, v), whose opposite corner is c.
struct Parallelogram {
  int u, v, c;
};
struct Predictors {
  std::vector<std::uint32_t> start;  // n + 1 offsets into list
  std::vector<Parallelogram> list;
  LowerNeighbours lower;
};

Predictors predictors(const std::vector<std::vector<int>>& faces, const std::vector<std::pair<int, int>>& edges,
                      int n) {
  Predictors p;
  p.lower = lower_neighbours(edges, n);
  std::vector<std::pair<std::uint64_t, int>> opposite;  // directed edge key -> third vertex
  auto key = [](int u, int v) {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(u)) << 32) | static_cast<std::uint32_t>(v);
  };
  for (const auto& f : faces)
    if (f.size() == 3)
      for (int k = 0; k < 3; ++k) opposite.emplace_back(key(f[k], f[(k + 1) % 3]), f[(k + 2) % 3]);
  // First triangle in face order per directed edge: stable sort keeps face order among equals.
  std::stable_sort(opposite.begin(), opposite.end(),
                   [](const auto& x, const auto& y) { return x.first < y.first; });
  auto find_opposite = [&](int u, int v) {
    const auto it = std::lower_bound(opposite.begin(), opposite.end(), std::make_pair(key(u, v), -1),
                                     [](const auto& x, const auto& y) { return x.first < y.first; });
    return (it != opposite.end() && it->first == key(u, v)) ? it->second : -1;
  };
  std::vector<std::vector<Parallelogram>> per(static_cast<std::size_t>(n));
  for (const auto& f : faces) {
    const int s = static_cast<int>(f.size());
    for (int k = 0; k < s; ++k) {
      const int w = f[k];
      if (s == 3) {
        const int u = f[(k + 1) % 3], v = f[(k + 2) % 3];
        if (u > w || v > w) continue;
        const int c = find_opposite(v, u);
        if (c >= 0 && c < w) per[w].push_back({u, v, c});
      } else {
        const int u = f[(k + 1) % 4], c = f[(k + 2) % 4], v = f[(k + 3) % 4];
        if (u < w && v < w && c < w) per[w].push_back({u, v, c});
      }
    }
  }
  p.start.assign(static_cast<std::size_t>(n) + 1, 0);
  for (int w = 0; w < n; ++w) {
    p.start[w + 1] = p.start[w] + static_cast<std::uint32_t>(per[w].size());
    p.list.insert(p.list.end(), per[w].begin(), per[w].end());
  }
  return p;
}

// floor((num + den / 2) / den) for den > 0: the mean rounded half up, also for negative sums.
std::int64_t rounded_mean(std::int64_t num, std::int64_t den) {
  const std::int64_t t = num + den / 2;
  return t >= 0 ? t / den : -((-t + den - 1) / den);
}

// Prediction of grid(w, a) and its kind (0 parallelogram used, 1 neighbours only, 2 neither).
std::pair<std::int64_t, int> predict_v3(const GridPoints& g, int w, int a, int mode, const Predictors& p,
                                        std::int64_t max_value) {
  if (mode == kPrevious) return {w > 0 ? g(w - 1, a) : 0, 2};
  const std::uint32_t plo = p.start[w], phi = p.start[w + 1];
  const std::uint32_t nlo = p.lower.start[w], nhi = p.lower.start[w + 1];
  std::int64_t para = 0, mean = 0;
  if (phi > plo) {
    std::int64_t s = 0;
    for (std::uint32_t k = plo; k < phi; ++k) {
      const Parallelogram& q = p.list[k];
      s += static_cast<std::int64_t>(g(q.u, a)) + g(q.v, a) - g(q.c, a);
    }
    para = std::clamp<std::int64_t>(rounded_mean(s, phi - plo), 0, max_value);
  }
  if (nhi > nlo) {
    std::int64_t s = 0;
    for (std::uint32_t k = nlo; k < nhi; ++k) s += g(p.lower.list[k], a);
    mean = rounded_mean(s, nhi - nlo);
  }
  if (phi > plo && nhi > nlo) {
    if (mode == kParallelogramFirst) return {para, 0};
    if (mode == kNeighboursFirst) return {mean, 1};
    return {(para + mean) / 2, 0};  // both in [0, max]: no rounding subtleties
  }
  if (nhi > nlo) return {mean, 1};
  return {w > 0 ? g(w - 1, a) : 0, 2};
}

struct CoordModels {
  std::array<BitModel, 3> zero{}, sign{};
  std::array<EgModels, 3> magnitude{};
  std::array<std::array<BitModel, 2>, 3> copy{};  // [distinct candidates - 1, capped][previous axis copied]
  std::array<BitModel, 4> which{};               // truncated unary over the candidates
};

// CAD parts have many axis-aligned planes, so a control vertex often repeats a coordinate of a
// neighbour exactly (a third to a half of them on the ABC parts). With copying on, each value
// first says whether it equals one of the distinct values its lower neighbours hold on that axis
// (ordered by how many neighbours hold it, then by distance to the prediction, then by value),
// and which; only other values are coded as residuals.
struct Candidate {
  std::int32_t value;
  int count;
};

void copy_candidates(const GridPoints& g, int w, int a, std::int64_t guess, const LowerNeighbours& lower,
                     std::vector<std::int32_t>& values, std::vector<Candidate>& out) {
  // Distinct values by sorting (not a search per value), so a vertex with many lower
  // neighbours costs O(d log d), not O(d^2).
  values.clear();
  for (std::uint32_t k = lower.start[w]; k < lower.start[w + 1]; ++k) values.push_back(g(lower.list[k], a));
  std::sort(values.begin(), values.end());
  out.clear();
  for (std::size_t i = 0; i < values.size();) {
    std::size_t j = i;
    while (j < values.size() && values[j] == values[i]) ++j;
    out.push_back({values[i], static_cast<int>(j - i)});
    i = j;
  }
  std::sort(out.begin(), out.end(), [&](const Candidate& x, const Candidate& y) {
    if (x.count != y.count) return x.count > y.count;
    const std::int64_t dx = std::abs(x.value - guess), dy = std::abs(y.value - guess);
    if (dx != dy) return dx < dy;
    return x.value < y.value;
  });
}

// One coordinate: a copy of a candidate (when `cands` is not empty, copying on) or a residual
// from `guess`. `copied` carries whether the previous axis of the vertex was copied.
template <class Coder>
void code_coordinate(Coder& rc, CoordModels& cm, int& copied, const std::vector<Candidate>& cands, int kind,
                     std::int64_t guess, std::int64_t value) {
  if (!cands.empty()) {
    std::size_t i = 0;
    while (i < cands.size() && cands[i].value != value) ++i;
    const int nc = static_cast<int>(std::min<std::size_t>(cands.size(), 3)) - 1;
    rc.bit(cm.copy[nc][copied], i < cands.size());
    copied = i < cands.size();
    if (copied) {
      for (std::size_t t = 0; t < i; ++t) rc.bit(cm.which[std::min<std::size_t>(t, 3)], 1);
      if (i + 1 < cands.size()) rc.bit(cm.which[std::min<std::size_t>(i, 3)], 0);
      return;
    }
  }
  const std::int64_t r = value - guess;
  rc.bit(cm.zero[kind], r != 0);
  if (r == 0) return;
  rc.bit(cm.sign[kind], r < 0);
  put_eg(rc, cm.magnitude[kind], static_cast<std::uint64_t>((r < 0 ? -r : r) - 1));
}

// Rate-distortion snapping for one coordinate mode: walks the vertices in stream order as the
// encoder does, and gives each coordinate, among the values within its vertex's allowance of
// the nearest grid value, the one that is cheapest to code under the models' state at that
// point plus a penalty of kSnapBitsPerCell bits per cell moved (ties: the nearest). Candidates are the values a prediction or copy makes cheap: the
// prediction itself, the copy candidates, and the values between the nearest one and the
// prediction (smaller residuals). Later predictions see the snapped values, as the decoder
// will. Greedy: a choice is never revisited.
// A move must save at least this much per cell: without it the greedy choice moves values for
// savings of a fraction of a bit that later decisions take back (abc5 at 8 bits, every
// coordinate allowed 1 cell: 370 bytes without the penalty, 360 with 1 bit per cell, and a
// lower RMS error).
constexpr double kSnapBitsPerCell = 1.0;

GridPoints snap_for_mode(const GridPoints& grid, const std::vector<std::uint8_t>& allowance, int mode,
                         const Predictors& pred, std::int64_t max_value) {
  GridPoints g = grid;
  const int n = static_cast<int>(g.rows());
  if (n == 0) return g;
  // The grid (cell size and origin) is derived from each axis's extreme values; they stay put
  // and nothing moves beyond them, so encoding the decoded positions again finds the same grid
  // and reproduces the stream.
  const Eigen::Array<std::int32_t, 1, 3> axis_min = grid.colwise().minCoeff(), axis_max = grid.colwise().maxCoeff();
  CoordModels cm;
  RangeEncoder rc(false);  // adapts the models exactly as the real encoder will; its bytes are dropped
  std::vector<Candidate> cands;
  std::vector<std::int32_t> scratch, options;
  for (int v = 0; v < n; ++v) {
    int copied = 0;
    for (int a = 0; a < 3; ++a) {
      const std::int64_t x0 = grid(v, a);
      const std::int64_t k =
          (x0 == axis_min[a] || x0 == axis_max[a]) ? 0 : allowance[3 * static_cast<std::size_t>(v) + a];
      const auto [guess, kind] = predict_v3(g, v, a, mode & 3, pred, max_value);
      if (mode & 4) copy_candidates(g, v, a, guess, pred.lower, scratch, cands);
      else cands.clear();
      std::int64_t best = x0;
      if (k > 0) {
        options.clear();
        const std::int64_t lo = std::max<std::int64_t>(axis_min[a], x0 - k), hi = std::min<std::int64_t>(axis_max[a], x0 + k);
        // Toward the prediction, up to it or the allowance.
        const std::int64_t toward = std::clamp(guess, lo, hi);
        for (std::int64_t y = std::min(x0, toward); y <= std::max(x0, toward); ++y)
          options.push_back(static_cast<std::int32_t>(y));
        for (const Candidate& c : cands)
          if (c.value >= lo && c.value <= hi) options.push_back(c.value);
        std::uint64_t best_cost = 0;
        bool first = true;
        for (std::int32_t y : options) {
          CostCounter cost;
          int copied_here = copied;
          code_coordinate(cost, cm, copied_here, cands, kind, guess, y);
          const std::int64_t d = std::abs(y - x0), bd = std::abs(best - x0);
          cost.cost += static_cast<std::uint64_t>(256 * kSnapBitsPerCell * d);
          if (first || cost.cost < best_cost || (cost.cost == best_cost && (d < bd || (d == bd && y < best)))) {
            best = y;
            best_cost = cost.cost;
            first = false;
          }
        }
      }
      g(v, a) = static_cast<std::int32_t>(best);
      code_coordinate(rc, cm, copied, cands, kind, guess, best);
    }
  }
  return g;
}

// ---------------------------------------------------------------------------------------------
// Creases: one flag per edge in sorted order, with the angle between the normals of its two
// faces (computed exactly in integers from the grid) and the crease edges already flagged at
// its endpoints as context. Corners: one flag per vertex, context its crease edge count.

// Faces' normals from grid values, scaled down to at most 2^20 per component (integer only,
// so every platform agrees).
using Normal = std::array<std::int64_t, 3>;
Normal face_normal(const GridPoints& g, const std::vector<int>& f) {
  auto d = [&](int i, int j, int a) { return static_cast<std::int64_t>(g(j, a)) - g(i, a); };
  std::int64_t e1[3], e2[3];
  if (f.size() == 3) {
    for (int a = 0; a < 3; ++a) e1[a] = d(f[0], f[1], a), e2[a] = d(f[0], f[2], a);
  } else {
    for (int a = 0; a < 3; ++a) e1[a] = d(f[0], f[2], a), e2[a] = d(f[1], f[3], a);
  }
  Normal n = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
  std::int64_t big = 0;
  for (std::int64_t c : n) big = std::max(big, c < 0 ? -c : c);
  std::int64_t div = 1;
  while (big / div >= (1 << 20)) div *= 2;
  for (auto& c : n) c /= div;
  return n;
}

// Angle class between two normals: 0 below ~14 degrees, 1 below 30, 2 below 50, 3 below 90,
// 4 at 90 or more, 5 a degenerate face.
int angle_class(const Normal& a, const Normal& b) {
  __extension__ typedef __int128 i128;
  const i128 dot = static_cast<i128>(a[0]) * b[0] + static_cast<i128>(a[1]) * b[1] + static_cast<i128>(a[2]) * b[2];
  const i128 na = static_cast<i128>(a[0]) * a[0] + static_cast<i128>(a[1]) * a[1] + static_cast<i128>(a[2]) * a[2];
  const i128 nb = static_cast<i128>(b[0]) * b[0] + static_cast<i128>(b[1]) * b[1] + static_cast<i128>(b[2]) * b[2];
  if (na == 0 || nb == 0) return 5;
  if (dot <= 0) return 4;
  // cos^2 against 0.97^2, 0.87^2, 0.64^2 as fractions over 10000.
  const i128 lhs = dot * dot * 10000, rhs = na * nb;
  if (lhs > rhs * 9409) return 0;
  if (lhs > rhs * 7569) return 1;
  if (lhs > rhs * 4096) return 2;
  return 3;
}

// Per edge (sorted order): its angle class, or 6 when it does not have exactly two faces.
std::vector<std::uint8_t> edge_classes(const std::vector<std::vector<int>>& faces,
                                       const std::vector<std::pair<int, int>>& edges, const GridPoints& g) {
  std::vector<std::array<int, 3>> by_edge;  // (lo, hi, face)
  by_edge.reserve(faces.size() * 4);
  for (std::size_t f = 0; f < faces.size(); ++f)
    for (std::size_t k = 0; k < faces[f].size(); ++k) {
      const int u = faces[f][k], v = faces[f][(k + 1) % faces[f].size()];
      by_edge.push_back({std::min(u, v), std::max(u, v), static_cast<int>(f)});
    }
  std::sort(by_edge.begin(), by_edge.end());
  std::vector<std::uint8_t> out(edges.size(), 6);
  std::size_t i = 0;
  for (std::size_t e = 0; e < edges.size(); ++e) {
    std::size_t j = i;
    while (j < by_edge.size() && by_edge[j][0] == edges[e].first && by_edge[j][1] == edges[e].second) ++j;
    if (j - i == 2)
      out[e] = static_cast<std::uint8_t>(
          angle_class(face_normal(g, faces[by_edge[i][2]]), face_normal(g, faces[by_edge[i + 1][2]])));
    i = j;
  }
  return out;
}

struct FeatureModels {
  std::array<std::array<BitModel, 6>, 7> crease{};  // [angle class][endpoint crease counts]
  std::array<BitModel, 4> corner{};                 // [crease edges at the vertex, capped]
};

int count_context(int ci, int cj) {
  const int a = std::min(std::min(ci, cj), 2), b = std::min(std::max(ci, cj), 2);
  return a == 0 ? b : (a == 1 ? 2 + b : 5);  // (0,0..2) -> 0..2, (1,1..2) -> 3..4, (2,2) -> 5
}

// ---------------------------------------------------------------------------------------------
// Header

constexpr std::uint64_t kElementsPerByte = 64, kElementsFloor = 1u << 16;

// metadata["levels"] travels in the header when it is "1".."7".
int levels_code(const std::map<std::string, std::string>& metadata) {
  const auto it = metadata.find("levels");
  if (it == metadata.end() || it->second.size() != 1 || it->second[0] < '1' || it->second[0] > '7') return 0;
  return it->second[0] - '0';
}

// The header and the faces are the same for every coordinate mode, so they are coded once and
// the coder's state is copied for each mode.
std::vector<std::uint8_t> header_bytes(const Mesh& mesh, const Quantization& q, int levels) {
  Writer w;
  w.raw(kMagic, 4);
  // Version 4 only where version 3 cannot hold the bits, so every stream version 3 can hold
  // stays byte for byte what it was.
  const bool v4 = q.bits < kMinQuantBitsV3;
  w.u8(v4 ? 4 : 3);
  w.u8(static_cast<std::uint8_t>((q.bits - (v4 ? kMinQuantBits : kMinQuantBitsV3)) | (levels << 5)));
  // The cell grid (codec/quantize.h): exponent and cell origin per axis.
  const int exponent = std::ilogb(q.step);
  w.varint(zigzag(exponent));
  for (int a = 0; a < 3; ++a)
    w.varint(zigzag(static_cast<std::int64_t>(std::floor(std::ldexp(q.offset[a], -exponent)))));
  w.varint(static_cast<std::uint64_t>(mesh.num_vertices()));
  w.varint(mesh.faces.size());
  return std::move(w.bytes);
}

// Everything after the faces, for one mode, continuing `rc`.
void encode_rest(RangeEncoder& rc, const Mesh& mesh, const Quantization& q, const GridPoints& grid,
                 const std::map<std::string, std::string>& metadata, int mode,
                 const std::vector<std::pair<int, int>>& edges, const Predictors& pred,
                 const std::vector<std::uint8_t>& classes, SectionBits& sections) {
  const int n = mesh.num_vertices();
  std::uint64_t mark = rc.cost_256();
  auto section = [&](double SectionBits::*field) {
    sections.*field = (rc.cost_256() - mark) / 256.0;
    mark = rc.cost_256();
  };
  rc.bits(static_cast<std::uint32_t>(mode), 3);
  CoordModels cm;
  std::vector<Candidate> cands;
  std::vector<std::int32_t> scratch;
  for (int v = 0; v < n; ++v) {
    int copied = 0;
    for (int a = 0; a < 3; ++a) {
      const auto [guess, kind] = predict_v3(grid, v, a, mode & 3, pred, q.max_value());
      if (mode & 4) copy_candidates(grid, v, a, guess, pred.lower, scratch, cands);
      else cands.clear();
      code_coordinate(rc, cm, copied, cands, kind, guess, grid(v, a));
    }
  }
  section(&SectionBits::coordinates);

  std::vector<char> crease(edges.size(), 0);
  for (auto [a, b] : mesh.creases) {
    if (a > b) std::swap(a, b);
    crease[std::lower_bound(edges.begin(), edges.end(), std::make_pair(a, b)) - edges.begin()] = 1;
  }
  FeatureModels xm;
  std::vector<int> crease_degree(static_cast<std::size_t>(n), 0);
  for (std::size_t e = 0; e < edges.size(); ++e) {
    const auto [a, b] = edges[e];
    rc.bit(xm.crease[classes[e]][count_context(crease_degree[a], crease_degree[b])], crease[e]);
    if (crease[e]) ++crease_degree[a], ++crease_degree[b];
  }
  section(&SectionBits::creases);
  std::vector<char> corner(static_cast<std::size_t>(n), 0);
  for (int c : mesh.corners) corner[c] = 1;
  for (int v = 0; v < n; ++v) rc.bit(xm.corner[std::min(crease_degree[v], 3)], corner[v]);
  section(&SectionBits::corners);

  const int levels = levels_code(metadata);
  EgModels count, length;
  std::vector<std::pair<std::string, std::string>> entries;
  for (const auto& kv : metadata)
    if (!(levels != 0 && kv.first == "levels")) entries.push_back(kv);
  put_eg(rc, count, entries.size());
  for (const auto& [k, v] : entries) {
    rc.bits(static_cast<std::uint32_t>(k.size() - 1), 6);
    for (char c : k) rc.bits(static_cast<std::uint8_t>(c), 8);
    put_eg(rc, length, v.size());
    for (char c : v) rc.bits(static_cast<std::uint8_t>(c), 8);
  }
  section(&SectionBits::metadata);
}

}  // namespace

std::vector<std::uint8_t> encode_v3(const Mesh& mesh, const Quantization& q, const GridPoints& grid,
                                    const std::map<std::string, std::string>& metadata, SectionBits* bits,
                                    const std::vector<std::uint8_t>* snap) {
  const int n = mesh.num_vertices();
  const auto head = header_bytes(mesh, q, levels_code(metadata));
  RangeEncoder after_faces(bits != nullptr);  // the copies below count costs for `bits` only
  FaceModels fm;
  RangeFaceSink sink(after_faces, fm);
  std::vector<std::vector<int>> faces;
  encode_faces(mesh.faces, n, &faces, sink);
  const auto edges = unique_edges(mesh);
  const Predictors pred = predictors(faces, edges, n);

  // Bits 0-1: the prediction; bit 2: coordinate copying.
  constexpr int kModes[] = {4, 5, 6, 0, 1, 2, 3};
  // The grids to try: the nearest values, then with snapping one grid per mode (snapped for
  // that mode's predictions). Every grid is coded with every mode and the smallest stream kept
  // (ties: the first), so the result is exactly what encoding its decoded grid without
  // snapping gives, and never larger than without snapping.
  std::vector<GridPoints> grids{grid};
  if (snap)
    for (int mode : kModes) {
      GridPoints g = snap_for_mode(grid, *snap, mode, pred, q.max_value());
      if (std::none_of(grids.begin(), grids.end(), [&](const GridPoints& o) { return o == g; }))
        grids.push_back(std::move(g));
    }

  std::vector<std::uint8_t> best;
  for (const GridPoints& g : grids) {
    const auto classes = edge_classes(faces, edges, g);
    for (int mode : kModes) {
      RangeEncoder rc = after_faces;
      SectionBits sb;
      sb.header_bytes = head.size();
      sb.faces = after_faces.cost_256() / 256.0;
      encode_rest(rc, mesh, q, g, metadata, mode, edges, pred, classes, sb);
      const auto body = rc.finish();
      std::vector<std::uint8_t> s = head;
      s.insert(s.end(), body.begin(), body.end());
      const std::uint32_t crc = checksum(s.data(), s.size());
      for (int i = 0; i < 4; ++i) s.push_back(static_cast<std::uint8_t>(crc >> (8 * i)));
      if (best.empty() || s.size() < best.size()) {
        best = std::move(s);
        if (bits) *bits = sb;
      }
    }
  }
  return best;
}

DecodedStream decode_v3(const std::uint8_t* data, std::size_t size, const std::string& source) {
  const std::size_t body_end = size - kChecksumBytes;
  Reader in(data + 5, body_end - 5, source, "header");
  DecodedStream out;
  out.version = data[4];
  const std::uint8_t packed = in.u8("quantisation bits");
  Quantization& q = out.quantization;
  // Version 4 holds exactly the bits version 3 cannot (one way to write each stream).
  const int lowest = out.version == 4 ? kMinQuantBits : kMinQuantBitsV3;
  const int highest = out.version == 4 ? kMinQuantBitsV3 - 1 : kMaxQuantBits;
  q.bits = (packed & 31) + lowest;
  const int levels = packed >> 5;
  if (q.bits > highest)
    in.fail("quantisation bits " + std::to_string(q.bits) + " outside [" + std::to_string(lowest) + ", " +
            std::to_string(highest) + "] for format version " + std::to_string(out.version));
  const std::int64_t exponent = unzigzag(in.varint("cell exponent", 0xFFFFFFFFull));
  if (exponent < kMinCellExponent || exponent > kMaxCellExponent)
    in.fail("cell exponent " + std::to_string(exponent) + " outside [" + std::to_string(kMinCellExponent) + ", " +
            std::to_string(kMaxCellExponent) + "]");
  q.step = std::ldexp(1.0, static_cast<int>(exponent));
  for (int a = 0; a < 3; ++a) {
    const std::int64_t o = unzigzag(in.varint("cell origin", 1ull << 60));
    if (o < -kMaxCellNumber || o + q.max_value() > kMaxCellNumber)
      in.fail("cell origin " + std::to_string(o) + " puts the grid beyond the cell number limit");
    q.offset[a] = std::ldexp(2.0 * static_cast<double>(o) + 1.0, static_cast<int>(exponent) - 1);
    const double far = std::ldexp(2.0 * static_cast<double>(o + q.max_value()) + 1.0, static_cast<int>(exponent) - 1);
    if (!std::isfinite(q.offset[a]) || !std::isfinite(far)) in.fail("transform maps the grid beyond the finite range");
  }
  const std::uint64_t nv = in.varint("vertex count", kMaxStreamVertices);
  const std::uint64_t nf = in.varint("face count", kMaxStreamFaces);
  const std::size_t body_size = in.remaining();
  // An arithmetic coder can code a likely decision in a tiny fraction of a bit, so the counts
  // are bounded by the body size (and a floor for small streams) before anything is allocated.
  const std::uint64_t cap = std::max<std::uint64_t>(kElementsFloor, kElementsPerByte * body_size);
  if (nv + nf > cap)
    in.fail(std::to_string(nv) + " vertices and " + std::to_string(nf) + " faces are more than a " +
            std::to_string(body_size) + "-byte body can hold (at most " + std::to_string(cap) + ")");
  const int n = static_cast<int>(nv);
  const std::uint8_t* body = in.position();
  if (body_size > 0 && body[body_size - 1] == 0) in.fail("range-coded body ends in a zero byte (not canonical)");

  BodyReader br(body, body_size, source);
  FaceModels fm;
  RangeFaceSource src(br, fm);
  Mesh& mesh = out.mesh;
  mesh.faces = decode_faces(src, static_cast<std::uint32_t>(nf), n);
  const int mode = static_cast<int>(br.bits(3));

  const auto edges = unique_edges(mesh);
  const Predictors pred = predictors(mesh.faces, edges, n);
  CoordModels cm;
  out.grid.resize(n, 3);
  const std::int64_t top = q.max_value();
  std::vector<Candidate> cands;
  std::vector<std::int32_t> scratch;
  for (int v = 0; v < n; ++v) {
    int copied = 0;
    for (int a = 0; a < 3; ++a) {
      const auto [guess, kind] = predict_v3(out.grid, v, a, mode & 3, pred, top);
      if (mode & 4) {
        copy_candidates(out.grid, v, a, guess, pred.lower, scratch, cands);
        if (!cands.empty()) {
          const int nc = static_cast<int>(std::min<std::size_t>(cands.size(), 3)) - 1;
          copied = br.bit(cm.copy[nc][copied]);
          if (copied) {
            std::size_t i = 0;
            while (i + 1 < cands.size() && br.bit(cm.which[std::min<std::size_t>(i, 3)])) ++i;
            out.grid(v, a) = cands[i].value;
            continue;
          }
        }
      }
      std::int64_t r = 0;
      if (br.bit(cm.zero[kind])) {
        const bool negative = br.bit(cm.sign[kind]);
        r = 1 + static_cast<std::int64_t>(br.eg(cm.magnitude[kind], static_cast<std::uint64_t>(top), "coordinate residual"));
        if (negative) r = -r;
      }
      const std::int64_t value = guess + r;
      if (value < 0 || value > top)
        br.fail("coordinates: vertex " + std::to_string(v) + " coordinate outside the " + std::to_string(q.bits) +
                "-bit grid");
      out.grid(v, a) = static_cast<std::int32_t>(value);
    }
  }
  mesh.points = dequantize(out.grid, q);

  const auto classes = edge_classes(mesh.faces, edges, out.grid);
  FeatureModels xm;
  std::vector<int> crease_degree(static_cast<std::size_t>(n), 0);
  for (std::size_t e = 0; e < edges.size(); ++e) {
    const auto [a, b] = edges[e];
    if (br.bit(xm.crease[classes[e]][count_context(crease_degree[a], crease_degree[b])])) {
      mesh.creases.push_back(edges[e]);
      ++crease_degree[a], ++crease_degree[b];
    }
  }
  for (int v = 0; v < n; ++v)
    if (br.bit(xm.corner[std::min(crease_degree[v], 3)])) mesh.corners.push_back(v);

  EgModels count, length;
  const std::uint64_t entries = br.eg(count, kMaxMetadataEntries, "metadata entry count");
  if (levels != 0) out.metadata["levels"] = std::to_string(levels);
  std::string prev_key;
  for (std::uint64_t m = 0; m < entries; ++m) {
    std::string key(br.bits(6) + 1, ' ');
    for (char& c : key) c = static_cast<char>(br.bits(8));
    const std::uint64_t vlen = br.eg(length, kMaxValueBytes, "metadata value length");
    std::string value(vlen, ' ');
    for (char& c : value) c = static_cast<char>(br.bits(8));
    if (!valid_key(key)) br.fail("invalid metadata key");
    if (m > 0 && !(prev_key < key)) br.fail("metadata keys not strictly increasing");
    if (key == "levels" && (levels != 0 || levels_code({{key, value}}) != 0))
      br.fail("metadata 'levels' stored in the entries where the header holds it");
    prev_key = key;
    out.metadata.emplace(std::move(key), std::move(value));
  }
  if (br.rc.consumed() < body_size)
    br.fail(std::to_string(body_size - br.rc.consumed()) + " unexpected trailing bytes after the range-coded body");
  return out;
}

}  // namespace mm::codec_detail
