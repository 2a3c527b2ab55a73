#include "fitting/control_polyhedron.h"
#include "fitting/decimation_modules.h"

#include <algorithm>
#include <memory>
#include <set>
#include <stdexcept>

namespace mm {

using namespace fitting_detail;

// One decimation of the input in progress: the mesh, its flags and the decimater with its heap.
struct ControlDecimation::Impl {
  // The input as an OpenMesh mesh with its flags, built by the first call: every decimation
  // from the input starts from a copy (building it was a tenth of a growth round).
  OMesh input;
  std::vector<int> source;
  std::vector<char> is_corner;
  int split_vertices = 0;
  struct Round {
    explicit Round(const OMesh& input) : om(input) {}
    OMesh om;  // before dec: the decimater removes its properties from om when destroyed
    std::unique_ptr<Decimater> dec;
    ModFeatureQuadricT<OMesh>::Handle hq;
    ModFlipGuardT<OMesh>::Handle hn;
    ModSliverGuardT<OMesh>::Handle ha;
    ControlOptions options;  // of the decimation so far (target_vertices: where it stopped)
  };
  std::unique_ptr<Round> round;
  // Decimater::set_initial_verdicts for decimations with these options (importance and target
  // aside: they change only the costs).
  std::vector<signed char> verdicts;
  ControlOptions verdict_options;
};

ControlDecimation::ControlDecimation(const Mesh& mesh, const Features& features,
                                     const Segmentation& segmentation)
    : mesh_(mesh), features_(features), segmentation_(segmentation) {}
ControlDecimation::~ControlDecimation() = default;

namespace {
// Same locks and binary modules, so the same legal collapses on the input.
bool same_constraints(const ControlOptions& a, const ControlOptions& b) {
  return a.min_open_chain_interior == b.min_open_chain_interior && a.min_closed_loop == b.min_closed_loop &&
         a.max_normal_deviation_degrees == b.max_normal_deviation_degrees &&
         a.max_aspect_ratio == b.max_aspect_ratio &&
         a.aspect_ratio_on_feature_triangles == b.aspect_ratio_on_feature_triangles;
}
bool same_except_target(const ControlOptions& a, const ControlOptions& b) {
  return same_constraints(a, b) && a.importance == b.importance;
}
}  // namespace

ControlPolyhedron build_control_polyhedron(const Mesh& mesh, const Features& features,
                                           const Segmentation& segmentation,
                                           const ControlOptions& options) {
  return ControlDecimation(mesh, features, segmentation).build(options);
}

ControlPolyhedron ControlDecimation::build(const ControlOptions& options) {
  const Mesh& mesh = mesh_;
  const Segmentation& segmentation = segmentation_;
  const int n = mesh.num_vertices();
  const size_t target = static_cast<size_t>(std::max(options.target_vertices, 4));
  // A greedy decimation stopped at N vertices is the start of the same decimation to fewer:
  // with the same costs, continue it instead of starting again from the input.
  if (impl_ && impl_->round && same_except_target(impl_->round->options, options) &&
      target <= static_cast<size_t>(std::max(impl_->round->options.target_vertices, 4))) {
    Impl::Round& r = *impl_->round;
    r.dec->decimate_to(target, r.dec->module(r.hq));
    r.options.target_vertices = options.target_vertices;
    return extract();
  }
  if (!impl_) build_input();
  impl_->round.reset();
  impl_->round = std::make_unique<Impl::Round>(impl_->input);
  Impl::Round& round = *impl_->round;
  OMesh& om = round.om;
  const std::vector<int>& source = impl_->source;
  const std::vector<char>& is_corner = impl_->is_corner;

  std::vector<int> chain_of(om.n_vertices(), -1), chain_min;
  for (const auto& line : segmentation.polylines) {
    const bool closed = line.size() > 2 && line.front() == line.back();
    const int id = static_cast<int>(chain_min.size());
    chain_min.push_back(closed ? options.min_closed_loop : options.min_open_chain_interior);
    for (size_t k = 0; k < line.size(); ++k)
      if (!is_corner[line[k]]) chain_of[line[k]] = id;
  }

  round.dec = std::make_unique<Decimater>(om);
  Decimater& dec = *round.dec;
  auto& hq = round.hq;
  auto& hn = round.hn;
  auto& ha = round.ha;
  dec.add(hq);
  dec.add(hn);
  dec.module(hn).set_max_normal_deviation(options.max_normal_deviation_degrees);
  if (options.max_aspect_ratio > 0) {
    dec.add(ha);
    dec.module(ha).set_aspect_ratio(options.max_aspect_ratio);
    dec.module(ha).set_exempt_feature_triangles(!options.aspect_ratio_on_feature_triangles);
  }
  if (!dec.initialize()) throw std::logic_error("decimater modules failed to initialise");
  if (options.max_aspect_ratio > 0)
    dec.set_guards({&dec.module(ha), &dec.module(hn)});
  else
    dec.set_guards({&dec.module(hn)});
  dec.module(hq).set_chains(chain_of, chain_min);
  if (!same_constraints(impl_->verdict_options, options)) {
    impl_->verdicts.clear();
    impl_->verdict_options = options;
  }
  dec.set_initial_verdicts(&impl_->verdicts);
  if (!options.importance.empty()) {
    if (static_cast<int>(options.importance.size()) != n) {
      impl_->round.reset();
      throw std::invalid_argument("importance must have one value per vertex");
    }
    std::vector<double> imp(om.n_vertices());
    for (size_t v = 0; v < imp.size(); ++v) imp[v] = std::max(options.importance[source[v]], 1e-9);
    dec.module(hq).set_importance(imp);
  }
  om.update_face_normals();
  dec.decimate_to(target, dec.module(hq));
  round.options = options;
  return extract();
}

void ControlDecimation::build_input() {
  const Mesh& mesh = mesh_;
  const Features& features = features_;
  const int n = mesh.num_vertices();
  impl_ = std::make_unique<Impl>();
  OMesh& om = impl_->input;
  std::vector<int>& source = impl_->source;
  std::vector<OMesh::VertexHandle> vh(n);
  for (int i = 0; i < n; ++i) {
    vh[i] = om.add_vertex(OpenMesh::Vec3d(mesh.points(i, 0), mesh.points(i, 1), mesh.points(i, 2)));
    source.push_back(i);
  }
  auto add_tri = [&](int a, int b, int c) {
    if (a == b || b == c || a == c) return;
    if (om.add_face(vh[a], vh[b], vh[c]).is_valid()) return;
    // Non-manifold here: give this face its own copies of the vertices (a crack, not a crash).
    std::vector<OMesh::VertexHandle> dup;
    for (int i : {a, b, c}) {
      dup.push_back(om.add_vertex(om.point(vh[i])));
      source.push_back(i);
      ++impl_->split_vertices;
    }
    om.add_face(dup);
  };
  for (const auto& f : mesh.faces)
    for (size_t k = 1; k + 1 < f.size(); ++k) add_tri(f[0], f[k], f[k + 1]);
  if (om.n_faces() == 0) {
    impl_.reset();
    throw std::invalid_argument("mesh has no usable faces");
  }

  // Flags: sharp edges and their vertices are features; corners are locked.
  std::set<std::pair<int, int>> sharp(features.sharp_edges.begin(), features.sharp_edges.end());
  std::vector<char>& is_corner = impl_->is_corner;
  is_corner.assign(om.n_vertices(), 0);
  for (int c : features.corners) is_corner[c] = 1;
  for (auto e : om.edges()) {
    int a = source[om.from_vertex_handle(om.halfedge_handle(e, 0)).idx()];
    int b = source[om.to_vertex_handle(om.halfedge_handle(e, 0)).idx()];
    if (sharp.count({std::min(a, b), std::max(a, b)}) || om.is_boundary(e)) {
      om.status(e).set_feature(true);
      om.status(om.from_vertex_handle(om.halfedge_handle(e, 0))).set_feature(true);
      om.status(om.to_vertex_handle(om.halfedge_handle(e, 0))).set_feature(true);
    }
  }
  for (auto v : om.vertices()) {
    is_corner[v.idx()] = is_corner[source[v.idx()]];
    if (is_corner[v.idx()]) om.status(v).set_locked(true);
  }
}

ControlPolyhedron ControlDecimation::extract() const {
  const OMesh& om = impl_->round->om;
  const std::vector<int>& source = impl_->source;
  const std::vector<char>& is_corner = impl_->is_corner;
  ControlPolyhedron out;
  out.split_vertices = impl_->split_vertices;
  // Collect survivors in input order (deterministic, independent of OpenMesh internals).
  std::vector<int> new_index(om.n_vertices(), -1);
  for (auto v : om.vertices())
    if (!om.status(v).deleted() && !om.is_isolated(v)) {
      new_index[v.idx()] = static_cast<int>(out.source.size());
      out.source.push_back(source[v.idx()]);
    }
  out.mesh.points.resize(static_cast<Eigen::Index>(out.source.size()), 3);
  for (auto v : om.vertices())
    if (new_index[v.idx()] >= 0) {
      auto p = om.point(v);
      out.mesh.points.row(new_index[v.idx()]) << p[0], p[1], p[2];
      if (is_corner[v.idx()]) out.mesh.corners.push_back(new_index[v.idx()]);
    }
  for (auto f : om.faces()) {
    if (om.status(f).deleted()) continue;
    std::vector<int> face;
    for (auto v : om.fv_range(f)) face.push_back(new_index[v.idx()]);
    out.mesh.faces.push_back(face);
  }
  for (auto e : om.edges()) {
    if (om.status(e).deleted() || !om.status(e).feature()) continue;
    int a = new_index[om.from_vertex_handle(om.halfedge_handle(e, 0)).idx()];
    int b = new_index[om.to_vertex_handle(om.halfedge_handle(e, 0)).idx()];
    if (a >= 0 && b >= 0) out.mesh.creases.emplace_back(std::min(a, b), std::max(a, b));
  }
  std::sort(out.mesh.creases.begin(), out.mesh.creases.end());
  // A crease that fades out into a smooth surface ends in a dart (one crease edge), which the
  // subdivision rules treat as a smooth vertex; tagging it a corner would pull a spike.
  std::vector<int> crease_valence(out.mesh.num_vertices(), 0);
  for (auto [a, b] : out.mesh.creases) ++crease_valence[a], ++crease_valence[b];
  out.mesh.corners.erase(std::remove_if(out.mesh.corners.begin(), out.mesh.corners.end(),
                                        [&](int v) { return crease_valence[v] == 1; }),
                         out.mesh.corners.end());
  std::sort(out.mesh.corners.begin(), out.mesh.corners.end());
  return out;
}

}  // namespace mm
