#include "jobs/prepared_asset.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <new>
#include <optional>
#include <nlohmann/json.hpp>
#include <sstream>

#include "meshio/read_mesh.h"
#include "compression/compress_part.h"
#include "quality/surface_distance.h"
#include "subdivision/decompress.h"
#include "subdivision/subdivide.h"

namespace mm::jobs {

namespace {

constexpr char kPolyMagic[8] = {'M', 'M', 'P', 'O', 'L', 'Y', '0', '2'};

struct Writer {
  std::vector<std::uint8_t> out;
  void raw(const void* p, std::size_t n) {
    auto* b = static_cast<const std::uint8_t*>(p);
    out.insert(out.end(), b, b + n);
  }
  void u64(std::uint64_t v) {
    for (int i = 0; i < 8; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  void i32(std::int32_t v) {
    auto u = static_cast<std::uint32_t>(v);
    for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(u >> (8 * i)));
  }
  void f64(double d) {
    std::uint64_t u;
    std::memcpy(&u, &d, 8);
    u64(u);
  }
};

struct Reader {
  const std::vector<std::uint8_t>& in;
  const std::string& source;
  std::size_t pos = 0;
  [[noreturn]] void fail(const std::string& why) const { throw InputError(source, why); }
  void need(std::size_t n) const {
    if (n > in.size() - pos) fail("truncated prepared-asset record");
  }
  // 2 for the current format, 1 for records of the uncompressed era.
  void magic() {
    need(8);
    if (std::memcmp(in.data() + pos, kPolyMagic, 8) != 0) fail("not a prepared-asset record (bad magic)");
    pos += 8;
  }
  std::uint64_t u64() {
    need(8);
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= std::uint64_t(in[pos + i]) << (8 * i);
    pos += 8;
    return v;
  }
  std::int32_t i32() {
    need(4);
    std::uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= std::uint32_t(in[pos + i]) << (8 * i);
    pos += 4;
    return static_cast<std::int32_t>(v);
  }
  double f64() {
    std::uint64_t u = u64();
    double d;
    std::memcpy(&d, &u, 8);
    return d;
  }
  // A count that must fit in what is left, given each item takes at least item_bytes.
  std::uint64_t count(std::size_t item_bytes) {
    std::uint64_t n = u64();
    if (item_bytes > 0 && n > (in.size() - pos) / item_bytes) fail("count exceeds record size");
    return n;
  }
};

// ";fallback=30,25,20" (rows prepared before the fallback have none), or nothing when empty.
std::string fallback_key(const std::vector<double>& angles) {
  std::string k;
  for (double a : angles) k += (k.empty() ? ";fallback=" : ",") + shortest_text(a);
  return k;
}

}  // namespace

std::string PrepareParams::key() const {
  // v2: control polyhedron = compress(original, compression), dense Kirchhoff basis. Every
  // compression option changes the polyhedron, so all are in the key (doubles in shortest
  // round-trip form); max_control_vertices is not: it refuses, and it can stop a min_mark_vertices
  // step only when set below a few times min_mark_vertices (a row prepared under another cap is
  // then reused as it is). "verify=dense": rounds meet
  // the tolerance by the quality code's dense measurement (as `meshmark compress`).
  // rounds_schedule_key() and fit_sampling_key() spell out compress.cpp's constants, so a change
  // to them fits assets again; rows under other keys stay readable for the copies issued from
  // them.
  const CompressOptions& c = compression;
  return "prepare-v2;compress;verify=dense;tolerance=" + shortest_text(c.tolerance) + ";max_vertices=" + std::to_string(c.max_vertices) +
         ";levels=" + std::to_string(c.levels) + ";angle=" + shortest_text(c.angle_degrees) +
         ";max_rounds=" + std::to_string(c.max_rounds) + (PartOptions{}.extend ? ";extend=budget;splits=" + std::to_string(PartOptions{}.max_splits) : std::string()) +
         ";budget_rounds=" + std::to_string(kRoundsAtBudget) + (c.rail_quads ? ";quads=rail" : "") + rounds_schedule_key(c) + fit_sampling_key() +
         (c.seed != 1 ? ";seed=" + std::to_string(c.seed) : "") + fallback_key(fallback_angles) +
         (min_mark_vertices > 0 ? ";mark_min_vertices=" + std::to_string(min_mark_vertices) : "") +
         (max_copy_triangles > 0 ? ";copy_triangles=" + std::to_string(max_copy_triangles) : "") + ";basis=dense-kirchhoff";
}

int refine_for_mark(Mesh& control, int min_vertices, int max_vertices) {
  int steps = 0;
  while (control.num_vertices() < min_vertices) {
    SubdivisionOperator op = build_subdivision(control, 1);
    if (op.refined.num_vertices() > max_vertices) break;
    control = std::move(op.refined);
    ++steps;
  }
  return steps;
}

std::string ShapeSignature::to_json() const {
  nlohmann::json j;
  j["version"] = version;
  j["vertices"] = vertices;
  j["faces"] = faces;
  j["box"] = {box[0], box[1], box[2]};
  j["moments"] = {moments[0], moments[1], moments[2]};
  return j.dump();
}

ShapeSignature ShapeSignature::from_json(const std::string& text) {
  try {
    auto j = nlohmann::json::parse(text);
    ShapeSignature s;
    s.version = j.at("version").get<int>();
    if (s.version != ShapeSignature{}.version)
      throw InputError("shape signature", "version " + std::to_string(s.version) + " is not supported");
    s.vertices = j.at("vertices").get<int>();
    s.faces = j.at("faces").get<int>();
    for (int i = 0; i < 3; ++i) {
      s.box[i] = j.at("box").at(i).get<double>();
      s.moments[i] = j.at("moments").at(i).get<double>();
    }
    return s;
  } catch (const nlohmann::json::exception& e) {
    throw InputError("shape signature", std::string("malformed: ") + e.what());
  }
}

ShapeSignature shape_signature(const Mesh& mesh) {
  ShapeSignature s;
  s.vertices = mesh.num_vertices();
  s.faces = mesh.num_faces();
  if (mesh.num_vertices() == 0) return s;
  const Points& p = mesh.points;
  Eigen::Vector3d lo = p.colwise().minCoeff().transpose();
  Eigen::Vector3d hi = p.colwise().maxCoeff().transpose();
  double side = (hi - lo).maxCoeff();
  if (!(side > 0)) return s;
  // Surface integrals over fan-triangulated faces, in the box frame scaled to side 1:
  // int_T x dA = A c and int_T x x^T dA = A/12 (sum v v^T + s s^T) with s the vertex sum.
  double area = 0;
  Eigen::Vector3d first = Eigen::Vector3d::Zero();
  Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
  auto at = [&](int v) -> Eigen::Vector3d { return (p.row(v).transpose() - lo) / side; };
  for (const auto& f : mesh.faces) {
    if (f.size() < 3) continue;
    bool ok = true;
    for (int v : f) ok = ok && v >= 0 && v < mesh.num_vertices();
    if (!ok) continue;
    Eigen::Vector3d a = at(f[0]);
    for (std::size_t k = 1; k + 1 < f.size(); ++k) {
      Eigen::Vector3d b = at(f[k]), c = at(f[k + 1]);
      double t = 0.5 * (b - a).cross(c - a).norm();
      if (!(t > 0)) continue;
      Eigen::Vector3d sum = a + b + c;
      area += t;
      first += t * sum / 3.0;
      second += t / 12.0 * (a * a.transpose() + b * b.transpose() + c * c.transpose() + sum * sum.transpose());
    }
  }
  if (!(area > 0)) return s;
  Eigen::Vector3d mean = first / area;
  Eigen::Matrix3d cov = second / area - mean * mean.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  const double trace = std::max(1e-300, cov.trace());
  for (int i = 0; i < 3; ++i) s.moments[i] = std::max(0.0, es.eigenvalues()[i]) / trace;
  // Extents along the principal axes, relative to the largest: a rotated copy has the same.
  Eigen::Vector3d plo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), phi = -plo;
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    Eigen::Vector3d q = es.eigenvectors().transpose() * at(static_cast<int>(i));
    plo = plo.cwiseMin(q);
    phi = phi.cwiseMax(q);
  }
  Eigen::Vector3d ext = phi - plo;
  for (int i = 0; i < 3; ++i) s.box[i] = ext[i] / std::max(1e-300, ext.maxCoeff());
  return s;
}

double signature_distance(const ShapeSignature& a, const ShapeSignature& b) {
  if (a.version != b.version) return std::numeric_limits<double>::infinity();
  double d = 0;
  for (int i = 0; i < 3; ++i) d += std::abs(a.box[i] - b.box[i]);
  for (int i = 0; i < 3; ++i) d += 4.0 * std::abs(std::sqrt(a.moments[i]) - std::sqrt(b.moments[i]));
  return d;
}

namespace {

// Lowers result.levels to the highest level whose decoded copy has at most
// params.max_copy_triangles triangles, and takes the dense measurement there as the fit's
// numbers (the mark's budget is what they leave of the tolerance).
void choose_copy_levels(CompressResult& result, const MeasuredSurface& measured, const PrepareParams& params,
                        const std::string& source) {
  const long long limit = params.max_copy_triangles;
  if (limit <= 0 || !result.tolerance_met) return;
  const long long full = subdivided_triangle_count(result.control, result.levels);
  if (full <= limit) return;
  int level = result.levels - 1;
  while (level > 0 && subdivided_triangle_count(result.control, level) > limit) --level;
  const long long triangles = subdivided_triangle_count(result.control, level);
  const std::string over = "the copy decoded at level " + std::to_string(result.levels) + " would have " +
                           std::to_string(full) + " triangles, over the copy limit of " + std::to_string(limit) +
                           " (max_triangles)";
  if (triangles > limit)
    throw InputError(source, over + ", and so would the control polyhedron itself (" + std::to_string(triangles) + ")");
  const double tolerance = params.compression.tolerance;
  const std::optional<SurfaceDistance> d = decoded_distance_within(measured, result.control, level, tolerance);
  if (!d)
    throw InputError(source, over + "; decoded at level " + std::to_string(level) + " (" + std::to_string(triangles) +
                                 " triangles) it misses the tolerance of " + shortest_text(100 * tolerance) +
                                 " % of the diagonal; raise max_triangles or compression.tolerance");
  result.levels = level;
  result.stats.hausdorff = d->hausdorff;
  result.stats.rms = d->rms;
  result.stats.mean = d->mean;
  result.stats.diagonal = d->diagonal;
}

}  // namespace

PreparedAsset prepare_asset(const Mesh& original, const PrepareParams& params,
                            const std::string& source) {
  const int n = original.num_vertices();
  if (n < 4) throw InputError(source, "mesh has " + std::to_string(n) + " vertices; need at least 4");
  if (original.faces.empty()) throw InputError(source, "mesh has no faces");
  if (params.compression.max_vertices > params.max_control_vertices)
    throw std::invalid_argument("control vertex budget " + std::to_string(params.compression.max_vertices) +
                                " exceeds the dense spectral basis limit " +
                                std::to_string(params.max_control_vertices));
  PreparedAsset a;
  try {
    // The fit measures its surface at refined vertices only and can miss a narrow peak between
    // them; the dense measurement the CLI reports decides here too, so a protected part meets
    // the configured tolerance by the same numbers `meshmark compress` and `compare` give.
    // The original's samples and tree are built once, for every round and fallback angle.
    const MeasuredSurface measured(original);
    PartOptions po;
    po.fit = params.compression;
    po.angles = {params.compression.angle_degrees};
    // Smaller angles only: each adds creases the configured angle left smooth.
    for (const double angle : params.fallback_angles)
      if (angle < params.compression.angle_degrees) po.fallback_angles.push_back(angle);
    a.compression = fit_part(original, measured, po, source).kept().result;
    choose_copy_levels(a.compression, measured, params, source);
  } catch (const InputError&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw;  // may pass on a retry
  } catch (const std::exception& e) {
    // Deterministic (a singular fitting system, a refined size beyond the subdivision guard):
    // the same input fails the same way again, so this is the input's problem.
    throw InputError(source, std::string("cannot compress: ") + e.what());
  }
  a.control = a.compression.control;
  if (a.control.num_vertices() > params.max_control_vertices)
    throw InputError(source, "control polyhedron has " + std::to_string(a.control.num_vertices()) +
                                 " vertices; the dense spectral basis is limited to " +
                                 std::to_string(params.max_control_vertices) + " (config watermark.max_vertices)");
  a.normalization = a.compression.normalization;
  apply(a.normalization, a.control.points);
  a.refinements = refine_for_mark(a.control, params.min_mark_vertices, params.max_control_vertices);
  a.levels = std::max(0, a.compression.levels - a.refinements);
  a.signature = shape_signature(original);
  a.footprint = surface_footprint(original);
  a.basis = compute_basis(a.control);
  return a;
}

std::vector<std::uint8_t> encode_polyhedron(const PreparedAsset& a) {
  Writer w;
  w.raw(kPolyMagic, 8);
  const Mesh& m = a.control;
  w.u64(static_cast<std::uint64_t>(m.num_vertices()));
  for (int i = 0; i < m.num_vertices(); ++i)
    for (int k = 0; k < 3; ++k) w.f64(m.points(i, k));
  w.u64(m.faces.size());
  for (const auto& f : m.faces) {
    w.u64(f.size());
    for (int v : f) w.i32(v);
  }
  w.u64(m.creases.size());
  for (auto [i, j] : m.creases) {
    w.i32(i);
    w.i32(j);
  }
  w.u64(m.corners.size());
  for (int c : m.corners) w.i32(c);
  for (int k = 0; k < 3; ++k) w.f64(a.normalization.offset[k]);
  w.f64(a.normalization.scale);
  w.i32(a.levels);
  std::string sig = a.signature.to_json();
  w.u64(sig.size());
  w.raw(sig.data(), sig.size());
  return std::move(w.out);
}

PreparedAsset decode_prepared(const std::vector<std::uint8_t>& poly,
                              const std::vector<std::uint8_t>& basis, const std::string& source) {
  PreparedAsset a;
  {
    Reader r{poly, source};
    r.magic();
    auto n = r.count(24);
    a.control.points.resize(static_cast<Eigen::Index>(n), 3);
    for (std::uint64_t i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k) a.control.points(static_cast<Eigen::Index>(i), k) = r.f64();
    auto nf = r.count(8);
    a.control.faces.resize(nf);
    for (auto& f : a.control.faces) {
      auto s = r.count(4);
      f.resize(s);
      for (auto& v : f) {
        v = r.i32();
        if (v < 0 || static_cast<std::uint64_t>(v) >= n) r.fail("face index out of range");
      }
    }
    auto nc = r.count(8);
    a.control.creases.resize(nc);
    for (auto& e : a.control.creases) {
      e.first = r.i32();
      e.second = r.i32();
      if (e.first < 0 || e.second < 0 || static_cast<std::uint64_t>(e.first) >= n ||
          static_cast<std::uint64_t>(e.second) >= n)
        r.fail("crease index out of range");
    }
    auto nk = r.count(4);
    a.control.corners.resize(nk);
    for (auto& c : a.control.corners) {
      c = r.i32();
      if (c < 0 || static_cast<std::uint64_t>(c) >= n) r.fail("corner index out of range");
    }
    for (int k = 0; k < 3; ++k) a.normalization.offset[k] = r.f64();
    a.normalization.scale = r.f64();
    a.levels = r.i32();
    if (a.levels < 0 || a.levels > 8) r.fail("subdivision levels out of range");
    auto ns = r.count(1);
    std::string sig(reinterpret_cast<const char*>(poly.data() + r.pos), ns);
    r.pos += ns;
    a.signature = ShapeSignature::from_json(sig);
    if (r.pos != poly.size()) r.fail("trailing bytes after polyhedron record");
  }
  a.basis = deserialize_basis(basis, source);
  if (a.basis.num_vertices() != a.control.num_vertices())
    throw InputError(source, "basis size does not match the polyhedron");
  return a;
}

}  // namespace mm::jobs
