// Internal to workers/fitting: the OpenMesh mesh and the decimation modules the control
// polyhedron is built with (feature quadrics, flip and sliver guards, a lazily updated
// decimater). Not part of the library's interface.
#pragma once
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
// QuadricT needs vector_traits from the mesh headers above.
#include <OpenMesh/Core/Geometry/QuadricT.hh>
#include <OpenMesh/Tools/Decimater/BaseDecimaterT.hh>
#include <OpenMesh/Tools/Utils/HeapT.hh>
#include <OpenMesh/Tools/Decimater/ModBaseT.hh>
#include <algorithm>
#include <memory>
#include <cfloat>
#include <cmath>
#include <set>
#include <stdexcept>
#include <vector>

namespace mm::fitting_detail {

struct Traits : OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;
  using Normal = OpenMesh::Vec3d;
  VertexAttributes(OpenMesh::Attributes::Status);
  EdgeAttributes(OpenMesh::Attributes::Status);
  FaceAttributes(OpenMesh::Attributes::Status | OpenMesh::Attributes::Normal);
};
// OpenMesh 9's TriConnectivity::is_collapse_ok allocates and frees a temporary per-vertex
// property on every call (O(n) each), which made it the decimation's main cost. Same tests
// here with a local one-ring list; the Decimater calls this one (it names MeshT's member).
struct OMesh : OpenMesh::TriMesh_ArrayKernelT<Traits> {
  bool is_collapse_ok(HalfedgeHandle v0v1) {
    if (status(edge_handle(v0v1)).deleted()) return false;
    const HalfedgeHandle v1v0 = opposite_halfedge_handle(v0v1);
    const VertexHandle v0 = to_vertex_handle(v1v0), v1 = to_vertex_handle(v0v1);
    if (status(v0).deleted() || status(v1).deleted()) return false;
    // OpenMesh also asks for the face's valence to be 3; every face here is a triangle.
    const bool t01 = !is_boundary(v0v1);
    const bool t10 = !is_boundary(v1v0);
    const VertexHandle n01 = to_vertex_handle(next_halfedge_handle(v0v1));
    const VertexHandle n10 = to_vertex_handle(next_halfedge_handle(v1v0));
    // The edges v1-vl and vl-v0 must not both be boundary edges.
    for (auto [tri, h] : {std::make_pair(t01, v0v1), std::make_pair(t10, v1v0)})
      if (tri) {
        const HalfedgeHandle h1 = next_halfedge_handle(h), h2 = next_halfedge_handle(h1);
        if (is_boundary(opposite_halfedge_handle(h1)) && is_boundary(opposite_halfedge_handle(h2))) return false;
      }
    // The one-rings of v0 and v1 may share only the two opposite vertices.
    ring_.clear();
    any_outgoing(v1, [&](HalfedgeHandle h) {
      ring_.push_back(to_vertex_handle(h));
      return false;
    });
    if (any_outgoing(v0, [&](HalfedgeHandle h) {
          const VertexHandle w = to_vertex_handle(h);
          return std::find(ring_.begin(), ring_.end(), w) != ring_.end() && !(w == n01 && t01) && !(w == n10 && t10);
        }))
      return false;
    // An edge between two boundary vertices must be a boundary edge.
    if (is_boundary(v0) && is_boundary(v1) && !is_boundary(v0v1) && !is_boundary(v1v0)) return false;
    return true;
  }

  // pred(h) for the outgoing halfedges of v until one says true (then true). The same set as
  // voh_range without OpenMesh's generic circulator; for tests whose answer is order-free.
  template <class Pred>
  bool any_outgoing(VertexHandle v, Pred pred) const {
    const HalfedgeHandle start = halfedge_handle(v);
    if (!start.is_valid()) return false;
    HalfedgeHandle h = start;
    do {
      if (pred(h)) return true;
      h = cw_rotated_halfedge_handle(h);
    } while (h != start);
    return false;
  }

 private:
  std::vector<VertexHandle> ring_;
};
using OpenMesh::Geometry::Quadricd;

// Quadric error (Garland-Heckbert, area weighted face planes) plus, along sharp edges, planes
// through the edge perpendicular to each adjacent face, so moving a crease vertex off a curved
// crease costs as much as moving a surface vertex off the surface. It also keeps the crease
// polylines alive: when a polyline reaches its minimum size its vertices get locked, and when a
// collapse merges a crease edge with a plain one the survivor inherits the crease flag.
template <class MeshT>
class ModFeatureQuadricT : public OpenMesh::Decimater::ModBaseT<MeshT> {
 public:
  DECIMATING_MODULE(ModFeatureQuadricT, MeshT, FeatureQuadric);

  explicit ModFeatureQuadricT(MeshT& mesh) : Base(mesh, false) {
    mesh.add_property(quadric_);
    mesh.add_property(chain_);
    mesh.add_property(importance_);
    for (auto v : mesh.vertices()) mesh.property(importance_, v) = 1.0;
  }
  ~ModFeatureQuadricT() override {
    Base::mesh().remove_property(quadric_);
    Base::mesh().remove_property(chain_);
    Base::mesh().remove_property(importance_);
  }

  void set_importance(const std::vector<double>& per_vertex) {
    auto& m = Base::mesh();
    for (auto v : m.vertices()) m.property(importance_, v) = per_vertex[v.idx()];
  }

  // chain_of[v] = polyline id of a non-corner crease vertex, -1 otherwise; chain_min[id] = floor.
  void set_chains(const std::vector<int>& chain_of, const std::vector<int>& chain_min) {
    auto& m = Base::mesh();
    for (auto v : m.vertices()) m.property(chain_, v) = chain_of[v.idx()];
    chain_min_ = chain_min;
    chain_count_.assign(chain_min.size(), 0);
    members_.assign(chain_min.size(), {});
    for (auto v : m.vertices())
      if (chain_of[v.idx()] >= 0) {
        ++chain_count_[chain_of[v.idx()]];
        members_[chain_of[v.idx()]].push_back(v);
      }
    for (size_t c = 0; c < chain_min_.size(); ++c) lock_if_at_floor(static_cast<int>(c));
  }

  void initialize() override {
    auto& m = Base::mesh();
    for (auto v : m.vertices()) m.property(quadric_, v).clear();
    for (auto f : m.faces()) {
      auto h = m.halfedge_handle(f);
      auto v0 = m.to_vertex_handle(h), v1 = m.to_vertex_handle(m.next_halfedge_handle(h)),
           v2 = m.from_vertex_handle(h);
      OpenMesh::Vec3d p0 = m.point(v0), p1 = m.point(v1), p2 = m.point(v2);
      OpenMesh::Vec3d n = (p1 - p0) % (p2 - p0);
      double area = n.norm();
      if (area <= DBL_MIN) continue;
      n /= area;
      Quadricd q(n[0], n[1], n[2], -(p0 | n));
      q *= 0.5 * area;
      m.property(quadric_, v0) += q;
      m.property(quadric_, v1) += q;
      m.property(quadric_, v2) += q;
    }
    for (auto e : m.edges()) {
      if (!m.status(e).feature()) continue;
      for (int side = 0; side < 2; ++side) {
        auto h = m.halfedge_handle(e, side);
        if (m.is_boundary(h)) continue;
        auto a = m.from_vertex_handle(h), b = m.to_vertex_handle(h);
        OpenMesh::Vec3d d = m.point(b) - m.point(a);
        OpenMesh::Vec3d n = d % m.calc_face_normal(m.face_handle(h));
        double len = n.norm();
        if (len <= DBL_MIN) continue;
        n /= len;
        Quadricd q(n[0], n[1], n[2], -(m.point(a) | n));
        q *= d.sqrnorm();
        m.property(quadric_, a) += q;
        m.property(quadric_, b) += q;
      }
    }
  }

  float collapse_priority(const CollapseInfo& ci) override {
    auto& m = Base::mesh();
    Quadricd q = m.property(quadric_, ci.v0);
    q += m.property(quadric_, ci.v1);
    double err = q(ci.p1) * std::max(m.property(importance_, ci.v0), m.property(importance_, ci.v1));
    return static_cast<float>(std::max(err, 0.0));
  }

  void preprocess_collapse(const CollapseInfo& ci) override {
    // Edges v0-vl and v0-vr disappear into v1-vl and v1-vr: remember crease flags.
    auto& m = Base::mesh();
    merged_.clear();
    for (auto vx : {ci.vl, ci.vr}) {
      if (!vx.is_valid()) continue;
      auto h0 = m.find_halfedge(ci.v0, vx);
      if (h0.is_valid() && m.status(m.edge_handle(h0)).feature()) merged_.push_back(vx);
    }
  }

  void postprocess_collapse(const CollapseInfo& ci) override {
    auto& m = Base::mesh();
    m.property(quadric_, ci.v1) += m.property(quadric_, ci.v0);
    m.property(importance_, ci.v1) =
        std::max(m.property(importance_, ci.v1), m.property(importance_, ci.v0));
    for (auto vx : merged_) {
      auto h = m.find_halfedge(ci.v1, vx);
      if (h.is_valid()) m.status(m.edge_handle(h)).set_feature(true);
    }
    int c = m.property(chain_, ci.v0);
    if (c >= 0) {
      --chain_count_[c];
      lock_if_at_floor(c);
    }
  }

 private:
  void lock_if_at_floor(int c) {
    if (chain_count_[c] > chain_min_[c]) return;
    auto& m = Base::mesh();
    for (auto v : members_[c])
      if (!m.status(v).deleted()) m.status(v).set_locked(true);
  }

  OpenMesh::VPropHandleT<Quadricd> quadric_;
  OpenMesh::VPropHandleT<int> chain_;
  OpenMesh::VPropHandleT<double> importance_;
  std::vector<int> chain_min_, chain_count_;
  std::vector<std::vector<OMesh::VertexHandle>> members_;
  std::vector<OMesh::VertexHandle> merged_;
};


// OpenMesh's ModNormalFlippingT (reject a collapse that turns the normal of a triangle around
// v0, other than the two that vanish, by more than the limit), with the same arithmetic but
// without moving v0 in the mesh and OpenMesh's face circulators: it ran for every candidate.
template <class MeshT>
class ModFlipGuardT : public OpenMesh::Decimater::ModBaseT<MeshT> {
 public:
  DECIMATING_MODULE(ModFlipGuardT, MeshT, FlipGuard);
  explicit ModFlipGuardT(MeshT& mesh) : Base(mesh, true) {}
  void set_max_normal_deviation(double degrees) {
    const double max_deviation = degrees / 180.0 * M_PI;  // as ModNormalFlippingT
    min_cos_ = cos(max_deviation);
  }

  float collapse_priority(const CollapseInfo& ci) override {
    const auto& m = Base::mesh();
    const bool flips = m.any_outgoing(ci.v0, [&](auto h) {
      const auto f = m.face_handle(h);
      if (!f.is_valid() || f == ci.fl || f == ci.fr) return false;
      // calc_face_normal(f)'s corners in its order, v0 moved onto p1.
      const auto h0 = m.halfedge_handle(f), h1 = m.next_halfedge_handle(h0), h2 = m.next_halfedge_handle(h1);
      auto at = [&](decltype(h0) x) -> const OpenMesh::Vec3d& {
        const auto v = m.to_vertex_handle(x);
        return v == ci.v0 ? ci.p1 : m.point(v);
      };
      const OpenMesh::Vec3d n2 =
          static_cast<const typename MeshT::PolyMesh&>(m).calc_face_normal(at(h0), at(h1), at(h2));
      return dot(m.normal(f), n2) < min_cos_;
    });
    return float(flips ? Base::ILLEGAL_COLLAPSE : Base::LEGAL_COLLAPSE);
  }

 private:
  double min_cos_ = 0.0;
};

// OpenMesh's ModAspectRatioT (reject a collapse that leaves a triangle longer than `max` times
// its height, unless it improves the worst one), except for triangles whose three corners all
// lie on the feature network. Those span a strip between creases (an extrusion wall, a step,
// a chamfer, the annulus between two concentric rims) or a disc inside a crease loop: their
// shape is set by the creases, and a narrow strip needs long thin triangles. Guarding them kept
// hundreds of vertices along the rims of the ABC parts (abc8: the decimation could not go below
// 240 vertices; without the exemption 92).
template <class MeshT>
class ModSliverGuardT : public OpenMesh::Decimater::ModBaseT<MeshT> {
 public:
  DECIMATING_MODULE(ModSliverGuardT, MeshT, SliverGuard);
  explicit ModSliverGuardT(MeshT& mesh) : Base(mesh, true) {}
  void set_aspect_ratio(double max_aspect) { max_aspect_ = max_aspect; }
  void set_exempt_feature_triangles(bool exempt) { exempt_ = exempt; }

  float collapse_priority(const CollapseInfo& ci) override {
    // The worst guarded triangle around v0 after moving v0 onto v1; only when that is over the
    // limit the worst before, and then only until after reaches it (the same answer as
    // computing both: most candidates pass on the first). The decimater asks for v0's
    // candidates one after another, so v0's triangles (and the worst before) are kept until v0
    // changes or a collapse changes the mesh.
    if (ci.v0 != ring_v0_) load_ring(ci.v0);
    const bool f1 = Base::mesh().status(ci.v1).feature();
    double after = 0;
    bool over = false;
    for (const Corner& c : ring_) {
      if (c.v2 == ci.v1 || c.v3 == ci.v1) continue;
      if (exempt_ && f1 && c.features) continue;
      after = std::max(after, aspect(ci.p1, c.p2, c.p3, c.d1));
      if (!over && after > max_aspect_) {
        over = true;
        if (!before_known_) {
          before_ = worst_before();
          before_known_ = true;
        }
      }
      if (over && !(after < before_)) return float(Base::ILLEGAL_COLLAPSE);
    }
    return float(Base::LEGAL_COLLAPSE);
  }

  void postprocess_collapse(const CollapseInfo&) override { ring_v0_ = VertexHandle(); }

 private:
  using VertexHandle = typename MeshT::VertexHandle;
  struct Corner {
    VertexHandle v2, v3;  // the triangle v0 v2 v3
    OpenMesh::Vec3d p2, p3;
    double d1;  // |p2 - p3|^2, the same for every candidate
    bool features;  // v2 and v3 on the feature network
  };

  void load_ring(VertexHandle v0) {
    auto& m = Base::mesh();
    ring_.clear();
    m.any_outgoing(v0, [&](auto h) {
      if (!m.face_handle(h).is_valid()) return false;
      const auto v2 = m.to_vertex_handle(h), v3 = m.to_vertex_handle(m.next_halfedge_handle(h));
      const OpenMesh::Vec3d p2 = m.point(v2), p3 = m.point(v3);
      ring_.push_back({v2, v3, p2, p3, (p2 - p3).sqrnorm(), m.status(v2).feature() && m.status(v3).feature()});
      return false;
    });
    ring_v0_ = v0;
    before_known_ = false;
  }

  double worst_before() {
    auto& m = Base::mesh();
    const bool f0 = m.status(ring_v0_).feature();
    const OpenMesh::Vec3d p0 = m.point(ring_v0_);
    double before = 0;
    for (const Corner& c : ring_)
      if (!(exempt_ && f0 && c.features)) before = std::max(before, aspect(p0, c.p2, c.p3, c.d1));
    return before;
  }

  // Longest edge over its height (OpenMesh's definition); infinite for a degenerate triangle.
  // d1 = |b - c|^2.
  static double aspect(const OpenMesh::Vec3d& a, const OpenMesh::Vec3d& b, const OpenMesh::Vec3d& c, double d1) {
    const OpenMesh::Vec3d d0 = a - b, d2 = c - a;
    const double l2 = std::max(std::max(d0.sqrnorm(), d1), d2.sqrnorm());  // max({...})'s answer, no loop
    const double a2 = (d0 % d2).norm();
    return a2 > 0 ? l2 / a2 : DBL_MAX;
  }
  std::vector<Corner> ring_;
  VertexHandle ring_v0_;
  double before_ = 0;
  bool before_known_ = false;
  double max_aspect_ = 8.0;
  bool exempt_ = true;
};

// OpenMesh's DecimaterT (same heap, same collapse order, same result), except that a vertex's
// candidate collapses are ranked by the cost module first and checked for legality and by the
// binary modules (normal flip, aspect ratio) cheapest first, stopping at the first that passes.
// Those checks were most of the decimation's time, spent on candidates that could not win.
template <class MeshT, class CostModule>
class LazyDecimaterT : public OpenMesh::Decimater::BaseDecimaterT<MeshT> {
 public:
  using Base = OpenMesh::Decimater::BaseDecimaterT<MeshT>;
  using CollapseInfo = OpenMesh::Decimater::CollapseInfoT<MeshT>;
  using VertexHandle = typename MeshT::VertexHandle;
  using HalfedgeHandle = typename MeshT::HalfedgeHandle;

  explicit LazyDecimaterT(MeshT& mesh) : Base(mesh), mesh_(mesh) {
    mesh_.add_property(collapse_target_);
    mesh_.add_property(priority_);
    mesh_.add_property(heap_position_);
  }
  ~LazyDecimaterT() {
    mesh_.remove_property(collapse_target_);
    mesh_.remove_property(priority_);
    mesh_.remove_property(heap_position_);
  }

  // Decimates until `n_vertices` are left (of all vertices ever added, like DecimaterT) with the
  // cost module `cost`, which must be the one added as the non-binary module. A later call with
  // a smaller count continues the same collapse sequence (the heap is kept).
  // The binary modules, in the order they were added (BaseDecimaterT keeps its list private).
  void set_guards(std::vector<OpenMesh::Decimater::ModBaseT<MeshT>*> guards) { guards_ = std::move(guards); }

  // Whether each halfedge's collapse passes (legal, no binary module's veto) on the mesh as it
  // stands before the first collapse: 0 not known yet, 1 yes, -1 no. Decimations of the same
  // input with the same locks and binary modules but other costs (compress()'s growth rounds:
  // only the importance changes) can share it, which spares the checks of the initial heap.
  void set_initial_verdicts(std::vector<signed char>* verdicts) { verdicts_ = verdicts; }

  size_t decimate_to(size_t n_vertices, CostModule& cost) {
    if (!this->is_initialized() || n_vertices >= mesh_.n_vertices()) return 0;
    const size_t wanted = mesh_.n_vertices() - n_vertices;
    cost_ = &cost;
    if (!heap_) {
      heap_ = std::make_unique<Heap>(HeapInterface{mesh_, priority_, heap_position_});
      heap_->reserve(mesh_.n_vertices());
      if (verdicts_) verdicts_->resize(mesh_.n_halfedges(), 0);
      initial_ = verdicts_ != nullptr;
      for (auto v : mesh_.vertices()) {
        heap_->reset_heap_position(v);
        if (!mesh_.status(v).deleted()) heap_vertex(v);
      }
      initial_ = false;
    }
    Heap& heap = *heap_;
    const bool update_normals = mesh_.has_face_normals();
    std::vector<VertexHandle> support;
    const size_t before = collapsed_;
    while (!heap.empty() && collapsed_ < wanted) {
      const VertexHandle vp = heap.front();
      const HalfedgeHandle v0v1 = mesh_.property(collapse_target_, vp);
      heap.pop_front();
      CollapseInfo ci(mesh_, v0v1);
      if (!legal(ci)) continue;
      support.clear();
      for (auto w : mesh_.vv_range(ci.v0)) support.push_back(w);
      this->preprocess_collapse(ci);
      mesh_.collapse(v0v1);
      ++collapsed_;
      if (update_normals)
        for (auto f : mesh_.vf_range(ci.v1))
          if (!mesh_.status(f).deleted()) mesh_.set_normal(f, mesh_.calc_face_normal(f));
      this->postprocess_collapse(ci);
      for (auto w : support) heap_vertex(w);
    }
    return collapsed_ - before;
  }

 private:
  struct HeapInterface {
    MeshT& mesh;
    OpenMesh::VPropHandleT<float> prio;
    OpenMesh::VPropHandleT<int> pos;
    bool less(VertexHandle a, VertexHandle b) { return mesh.property(prio, a) < mesh.property(prio, b); }
    bool greater(VertexHandle a, VertexHandle b) { return mesh.property(prio, a) > mesh.property(prio, b); }
    int get_heap_position(VertexHandle v) { return mesh.property(pos, v); }
    void set_heap_position(VertexHandle v, int p) { mesh.property(pos, v) = p; }
  };
  using Heap = OpenMesh::Utils::HeapT<VertexHandle, HeapInterface>;

  // BaseDecimaterT::is_collapse_legal's tests (with OMesh::is_collapse_ok's), the cheap flag
  // tests first and the one-ring tests last: the same answer, as each test only says no.
  bool legal(const CollapseInfo& ci) {
    if (mesh_.status(mesh_.edge_handle(ci.v0v1)).deleted() || mesh_.status(ci.v0).deleted() ||
        mesh_.status(ci.v1).deleted())
      return false;
    if (!cheap_legal(ci.v0, ci.v0v1)) return false;
    // There have to be at least 2 incident faces at v0.
    if (mesh_.cw_rotated_halfedge_handle(mesh_.cw_rotated_halfedge_handle(ci.v0v1)) == ci.v0v1) return false;
    if (mesh_.is_boundary(ci.v0) && ci.vl.is_valid() && ci.vr.is_valid()) return false;
    if (!mesh_.is_collapse_ok(ci.v0v1)) return false;
    // vl and vr joined by an edge and both of valence 3: valence first, it stops after 4.
    if (ci.vl.is_valid() && ci.vr.is_valid() && valence_is_3(ci.vl) && valence_is_3(ci.vr) &&
        mesh_.any_outgoing(ci.vl, [&](HalfedgeHandle h) { return mesh_.to_vertex_handle(h) == ci.vr; }))
      return false;
    return true;
  }

  // The tests of legal() that depend on v0 and the edge only: locked, the feature rule, a
  // boundary vertex only onto a boundary vertex.
  bool cheap_legal(VertexHandle v0, HalfedgeHandle v0v1) {
    const auto s0 = mesh_.status(v0);
    if (s0.locked()) return false;
    if (s0.feature() && !mesh_.status(mesh_.edge_handle(v0v1)).feature()) return false;
    if (mesh_.is_boundary(v0) && !mesh_.is_boundary(mesh_.to_vertex_handle(v0v1))) return false;
    return true;
  }

  // Legal and not vetoed by a binary module (the cheap tests of legal() already passed). The
  // modules first: they only read the geometry around v0, and they say no to a third of the
  // candidates, legal() to almost none.
  bool passes(const CollapseInfo& ci) {
    for (auto* guard : guards_)
      if (guard->collapse_priority(ci) < 0.0f) return false;
    return legal(ci);
  }

  bool valence_is_3(VertexHandle v) {
    int n = 0;
    if (mesh_.any_outgoing(v, [&](HalfedgeHandle) { return ++n > 3; })) return false;
    return n == 3;
  }

  void heap_vertex(VertexHandle vh) {
    // Candidates by cost, ties in ring order (DecimaterT keeps the first of equal costs): the
    // first that is legal and passes the binary modules is DecimaterT's choice. Candidates
    // that fail the cheap tests of legal() are left out before their cost is computed (a
    // locked vertex has none).
    candidates_.clear();
    int order = 0;
    if (!mesh_.status(vh).locked())
      for (auto h : mesh_.voh_range(vh)) {
        ++order;
        if (!cheap_legal(vh, h)) continue;
        const float cost = cost_->collapse_priority(CollapseInfo(mesh_, h));
        if (cost >= 0.0f && cost < FLT_MAX) candidates_.push_back({cost, order, h});
      }
    std::sort(candidates_.begin(), candidates_.end(), [](const Candidate& a, const Candidate& b) {
      return a.cost < b.cost || (a.cost == b.cost && a.order < b.order);
    });
    float best = FLT_MAX;
    HalfedgeHandle target;
    for (const auto& cand : candidates_) {
      bool ok;
      if (initial_) {
        signed char& verdict = (*verdicts_)[cand.h.idx()];
        if (verdict == 0) verdict = passes(CollapseInfo(mesh_, cand.h)) ? 1 : -1;
        ok = verdict > 0;
      } else {
        ok = passes(CollapseInfo(mesh_, cand.h));
      }
      // Base::collapse_priority is the cost module's value (cand.cost, the same computation)
      // unless a binary module vetoes.
      if (ok) {
        best = cand.cost;
        target = cand.h;
        break;
      }
    }
    if (target.is_valid()) {
      mesh_.property(collapse_target_, vh) = target;
      mesh_.property(priority_, vh) = best;
      if (heap_->is_stored(vh))
        heap_->update(vh);
      else
        heap_->insert(vh);
    } else {
      if (heap_->is_stored(vh)) heap_->remove(vh);
      mesh_.property(collapse_target_, vh) = target;
      mesh_.property(priority_, vh) = -1;
    }
  }

  struct Candidate {
    float cost;
    int order;
    HalfedgeHandle h;
  };
  std::vector<Candidate> candidates_;
  std::vector<OpenMesh::Decimater::ModBaseT<MeshT>*> guards_;
  std::vector<signed char>* verdicts_ = nullptr;
  bool initial_ = false;  // building the initial heap with verdicts_
  MeshT& mesh_;
  CostModule* cost_ = nullptr;
  std::unique_ptr<Heap> heap_;
  size_t collapsed_ = 0;
  OpenMesh::VPropHandleT<HalfedgeHandle> collapse_target_;
  OpenMesh::VPropHandleT<float> priority_;
  OpenMesh::VPropHandleT<int> heap_position_;
};

using Decimater = LazyDecimaterT<OMesh, ModFeatureQuadricT<OMesh>>;

}  // namespace mm::fitting_detail
