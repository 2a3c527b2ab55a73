#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <array>
#include <limits>
#include <map>
#include <thread>
#include <vector>

#include "common/shared_meshes.h"
#include "meshio/read_mesh.h"
#include "quality/surface_distance.h"

namespace {

// Flat n x n quad grid over [0, 1]^2 at z = 0.
mm::Mesh square_grid(int n) {
  mm::Mesh m;
  m.points.resize((n + 1) * (n + 1), 3);
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) m.points.row(j * (n + 1) + i) << double(i) / n, double(j) / n, 0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i;
      m.faces.push_back({a, a + 1, a + n + 2, a + n + 1});
    }
  return m;
}

// Closed unit cube of 6 quads.
mm::Mesh cube() {
  mm::Mesh m;
  m.points.resize(8, 3);
  for (int i = 0; i < 8; ++i) m.points.row(i) << (i & 1), (i >> 1) & 1, (i >> 2) & 1;
  m.faces = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  return m;
}

// Icosphere of radius 1: icosahedron subdivided `levels` times, projected to the sphere.
mm::Mesh icosphere(int levels) {
  const double t = (1 + std::sqrt(5.0)) / 2;
  std::vector<Eigen::Vector3d> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                                    {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                                    {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (auto& p : v) p.normalize();
  std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11},
                                       {1, 5, 9}, {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                       {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8}, {3, 8, 9},
                                       {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[a] + v[b]).normalized());
      return mid[key] = static_cast<int>(v.size()) - 1;
    };
    std::vector<std::array<int, 3>> next;
    for (const auto& tri : f) {
      const int ab = midpoint(tri[0], tri[1]), bc = midpoint(tri[1], tri[2]), ca = midpoint(tri[2], tri[0]);
      next.push_back({tri[0], ab, ca});
      next.push_back({tri[1], bc, ab});
      next.push_back({tri[2], ca, bc});
      next.push_back({ab, bc, ca});
    }
    f = next;
  }
  mm::Mesh m;
  m.points.resize(static_cast<int>(v.size()), 3);
  for (size_t i = 0; i < v.size(); ++i) m.points.row(i) = v[i].transpose();
  for (const auto& tri : f) m.faces.push_back({tri[0], tri[1], tri[2]});
  return m;
}

mm::SamplingParams fast() {
  mm::SamplingParams p;
  p.samples = 20000;
  return p;
}

}  // namespace

TEST(SurfaceDistance, IdenticalMeshesAreAtZero) {
  const mm::Mesh s = icosphere(3);
  const auto d = mm::surface_distance(s, s, fast());
  EXPECT_LT(d.hausdorff, 1e-12);
  EXPECT_LT(d.rms, 1e-12);
  EXPECT_LT(d.mean, 1e-12);
  EXPECT_NEAR(d.diagonal, 2 * std::sqrt(3.0), 0.05);  // the box of a unit sphere
  // 20,000 on average: each of the 1,280 triangles' shares rounded up or down at random.
  EXPECT_NEAR(static_cast<double>(d.a_to_b.samples), 20000.0 + s.num_vertices(), 200);
}

TEST(SurfaceDistance, TranslatedCopyIsAtTheTranslation) {
  // A flat square moved along its normal: every sample is exactly that far away.
  const mm::Mesh a = square_grid(8);
  mm::Mesh b = a;
  b.points.col(2).array() += 0.03;
  const auto d = mm::surface_distance(a, b, fast());
  EXPECT_NEAR(d.hausdorff, 0.03, 1e-12);
  EXPECT_NEAR(d.mean, 0.03, 1e-12);
  EXPECT_NEAR(d.rms, 0.03, 1e-12);
  EXPECT_NEAR(d.hausdorff_relative(), 0.03 / std::sqrt(2.0), 1e-12);
  // A cube moved sideways: the faces across the move are d apart, the others partly overlap,
  // so the Hausdorff distance is the move and the mean is smaller.
  const mm::Mesh c = cube();
  mm::Mesh moved = c;
  moved.points.col(0).array() += 0.1;
  const auto dc = mm::surface_distance(c, moved, fast());
  EXPECT_NEAR(dc.hausdorff, 0.1, 1e-9);
  EXPECT_LT(dc.mean, 0.1);
  EXPECT_GT(dc.mean, 0.0);
}

TEST(SurfaceDistance, SphereAgainstScaledSphere) {
  const mm::Mesh s = icosphere(4);  // chord sag below 1e-3
  mm::Mesh big = s;
  big.points *= 1.1;
  const auto d = mm::surface_distance(s, big, fast());
  EXPECT_NEAR(d.hausdorff, 0.1, 2e-3);
  EXPECT_NEAR(d.mean, 0.1, 2e-3);
  EXPECT_NEAR(d.rms, 0.1, 2e-3);
  EXPECT_LE(d.mean, d.rms);
  EXPECT_LE(d.rms, d.hausdorff);
}

TEST(SurfaceDistance, MissingPartShowsOnlyOneWay) {
  // b is a with the upper cap removed (all faces with a vertex above z = 0.6): b's samples all lie
  // on a, but a's cap samples are far from b.
  const mm::Mesh a = icosphere(3);
  mm::Mesh b = a;
  b.faces.clear();
  for (const auto& f : a.faces) {
    bool cap = false;
    for (int v : f) cap = cap || a.points(v, 2) > 0.6;
    if (!cap) b.faces.push_back(f);
  }
  ASSERT_LT(b.faces.size(), a.faces.size());
  const auto d = mm::surface_distance(a, b, fast());
  EXPECT_LT(d.b_to_a.max, 1e-12);
  EXPECT_GT(d.a_to_b.max, 0.3);  // the pole is ~0.4 from the cut rim
  EXPECT_EQ(d.hausdorff, d.a_to_b.max);
  EXPECT_EQ(d.mean, d.a_to_b.mean);
  // One-sided distance from the part to the whole sees nothing.
  EXPECT_LT(mm::one_sided_distance(b, a, fast()).max, 1e-12);
}

TEST(SurfaceDistance, SamplingIsAreaWeightedAndDeterministic) {
  // Two squares side by side, the second four times the area, as one mesh: samples split 1:4.
  mm::Mesh m;
  m.points.resize(8, 3);
  m.points << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 5, 0, 0, 7, 0, 0, 7, 2, 0, 5, 2, 0;
  m.faces = {{0, 1, 2, 3}, {4, 5, 6, 7}};
  const auto s = mm::sample_surface(m, 10000, 7, false);
  // Each of the four triangles gets its share (1,000 or 4,000) rounded up or down.
  ASSERT_NEAR(static_cast<double>(s.size()), 10000, 4);
  int small = 0;
  for (const auto& p : s) {
    small += p.x() <= 1;
    EXPECT_TRUE((p.x() >= 0 && p.x() <= 1 && p.y() >= 0 && p.y() <= 1) ||
                (p.x() >= 5 && p.x() <= 7 && p.y() >= 0 && p.y() <= 2));
  }
  EXPECT_NEAR(small, 2000, 2);
  EXPECT_EQ(mm::sample_surface(m, 100, 3, true), mm::sample_surface(m, 100, 3, true));
  EXPECT_NE(mm::sample_surface(m, 100, 3, false), mm::sample_surface(m, 100, 4, false));
  const mm::Mesh sphere = icosphere(2);
  mm::Mesh big = sphere;
  big.points *= 1.05;
  EXPECT_EQ(mm::surface_distance(sphere, big, fast()).rms, mm::surface_distance(sphere, big, fast()).rms);
}

// The same surface with its faces in another order, its vertices renumbered, each face starting
// at another corner and its coordinates off in their last bits (as a stream decodes it): the same
// set of samples, so the same distances and the same tolerance answers.
TEST(SurfaceDistance, TheSamplesDoNotDependOnHowTheSurfaceIsNumbered) {
  const mm::Mesh a = icosphere(3);
  mm::Mesh b;
  const int n = a.num_vertices();
  std::vector<int> renumber(n);
  for (int v = 0; v < n; ++v) renumber[v] = (v * 7919) % n;  // 7919 is prime, n = 642: a permutation
  b.points.resize(n, 3);
  for (int v = 0; v < n; ++v) b.points.row(renumber[v]) = a.points.row(v);
  for (std::size_t f = a.faces.size(); f-- > 0;) {
    const auto& face = a.faces[f];
    const int r = static_cast<int>(f % 3);
    b.faces.push_back({renumber[face[r]], renumber[face[(r + 1) % 3]], renumber[face[(r + 2) % 3]]});
  }
  const auto sorted = [](std::vector<Eigen::Vector3d> s) {
    std::sort(s.begin(), s.end(), [](const Eigen::Vector3d& p, const Eigen::Vector3d& q) {
      return std::lexicographical_compare(p.data(), p.data() + 3, q.data(), q.data() + 3);
    });
    return s;
  };
  const auto sa = sorted(mm::sample_surface(a, 5000, 11, true));
  const auto sb = sorted(mm::sample_surface(b, 5000, 11, true));
  ASSERT_EQ(sa.size(), sb.size());
  double worst = 0;
  for (std::size_t i = 0; i < sa.size(); ++i) worst = std::max(worst, (sa[i] - sb[i]).norm());
  EXPECT_LT(worst, 1e-15) << "the same points, up to the rounding of another corner order";
  mm::Mesh c = b;  // and off in the last bits
  for (int v = 0; v < n; ++v)
    for (int k = 0; k < 3; ++k) c.points(v, k) = std::nextafter(c.points(v, k), 2.0);
  EXPECT_EQ(mm::sample_surface(c, 5000, 11, false).size(), mm::sample_surface(a, 5000, 11, false).size());
  mm::Mesh big = a;
  big.points *= 1.01;
  const auto d_a = mm::surface_distance(big, a, fast()), d_c = mm::surface_distance(big, c, fast());
  EXPECT_NEAR(d_a.hausdorff, d_c.hausdorff, 1e-12);
  EXPECT_NEAR(d_a.rms, d_c.rms, 1e-12);
  const mm::MeasuredSurface measured(big, fast());
  for (double limit : {0.5 * d_a.hausdorff_relative(), 0.999 * d_a.hausdorff_relative(), 1.001 * d_a.hausdorff_relative()})
    EXPECT_EQ(mm::surface_within(measured, a, limit), mm::surface_within(measured, c, limit)) << limit;
}

TEST(SurfaceDistance, BadInputIsRefused) {
  mm::Mesh empty;
  empty.points.resize(0, 3);
  EXPECT_THROW(mm::surface_distance(cube(), empty), mm::InputError);
  mm::Mesh flat = cube();
  flat.points.col(2).setZero();
  flat.points.col(1).setZero();  // everything on a line: no area anywhere
  EXPECT_THROW(mm::surface_distance(cube(), flat), mm::InputError);
  mm::Mesh nan = cube();
  nan.points(2, 1) = std::nan("");
  EXPECT_THROW(mm::surface_distance(cube(), nan), mm::InputError);
  mm::Mesh bad = cube();
  bad.faces[0][0] = 42;
  EXPECT_THROW(mm::surface_distance(bad, cube()), mm::InputError);
}

TEST(SurfaceDistance, RealPartMovedSlightly) {
  MM_REQUIRE_SHARED_MESHES();
  // fandisk moved by 0.1% of its diagonal in a skew direction: no sample is farther than the
  // move, and the flat faces facing the move are nearly that far.
  const mm::Mesh a = mm::read_mesh(mm::test::shared_mesh("fandisk.off"));
  mm::Mesh b = a;
  const double diag = (a.points.colwise().maxCoeff() - a.points.colwise().minCoeff()).norm();
  const Eigen::RowVector3d move = Eigen::RowVector3d(1, 2, 2) / 3.0 * (0.001 * diag);
  b.points.rowwise() += move;
  const auto d = mm::surface_distance(a, b, fast());
  EXPECT_NEAR(d.diagonal, diag, 1e-12);
  EXPECT_LE(d.hausdorff, move.norm() * (1 + 1e-9));
  EXPECT_GT(d.hausdorff, 0.9 * move.norm());
  EXPECT_GT(d.mean, 0.2 * move.norm());
  EXPECT_NEAR(d.hausdorff_relative(), d.hausdorff / diag, 1e-15);
}

// A tolerance check (surface_distance_within): within the limit, surface_distance's numbers bit
// for bit, the limit itself included; beyond it, nothing, whether one sample or all of them lie
// beyond (a bump on one face of a sphere, or the whole sphere scaled).
TEST(SurfaceDistance, WithinALimitTheSameNumbersBeyondItNothing) {
  const mm::Mesh s = icosphere(3);
  mm::Mesh bumped = s;
  bumped.points.row(0) *= 1.2;  // one vertex out: a narrow cone on one side
  mm::Mesh big = s;
  big.points *= 1.1;
  for (const mm::Mesh* other : {&bumped, &big}) {
    const mm::SurfaceDistance whole = mm::surface_distance(s, *other, fast());
    const double h = whole.hausdorff_relative();
    ASSERT_GT(h, 0);
    for (double limit : {h, 2 * h, std::numeric_limits<double>::infinity()}) {
      const auto d = mm::surface_distance_within(s, *other, limit, fast());
      ASSERT_TRUE(d.has_value()) << limit;
      EXPECT_EQ(d->hausdorff, whole.hausdorff);
      EXPECT_EQ(d->rms, whole.rms);
      EXPECT_EQ(d->mean, whole.mean);
      EXPECT_EQ(d->a_to_b.mean, whole.a_to_b.mean);
      EXPECT_EQ(d->b_to_a.rms, whole.b_to_a.rms);
      EXPECT_EQ(d->a_to_b.samples, whole.a_to_b.samples);
    }
    EXPECT_FALSE(mm::surface_distance_within(s, *other, std::nextafter(h, 0.0), fast()).has_value());
    EXPECT_FALSE(mm::surface_distance_within(s, *other, 0.5 * h, fast()).has_value());
  }
  // The decoded form measures the subdivided control mesh, as decoded_distance does.
  const mm::Mesh control = icosphere(1);
  const mm::SurfaceDistance whole = mm::decoded_distance(s, control, 2, fast());
  const auto d = mm::decoded_distance_within(s, control, 2, whole.hausdorff_relative(), fast());
  ASSERT_TRUE(d.has_value());
  EXPECT_EQ(d->rms, whole.rms);
  EXPECT_FALSE(mm::decoded_distance_within(s, control, 2, 0.5 * whole.hausdorff_relative(), fast()).has_value());
}

// A sphere and what the tests measure against it: the sphere with one vertex out (a narrow cone
// on one side), the sphere scaled (off everywhere), and a coarse control mesh of it.
struct Sphere {
  mm::Mesh part = icosphere(3), bumped = part, big = part, control = icosphere(1);
  Sphere() {
    bumped.points.row(0) *= 1.2;
    big.points *= 1.1;
  }
};

// The answer alone (surface_within, decoded_within) is surface_distance's comparison exactly:
// at the distance itself, an ulp below it, and around it, for a surface off by a narrow peak,
// one off everywhere, and a subdivided control mesh (a compress verify's question).
TEST(SurfaceDistance, WithinIsTheComparisonOfTheWholeMeasurement) {
  const Sphere x;
  const mm::Mesh &s = x.part, &bumped = x.bumped, &big = x.big, &control = x.control;
  const mm::MeasuredSurface part(s, fast());
  const auto check = [](double h, const std::function<bool(double)>& within) {
    ASSERT_GT(h, 0);
    for (double limit : {h, std::nextafter(h, 0.0), std::nextafter(h, 1.0), h * (1 - 1e-13), h * (1 + 1e-13),
                         0.999 * h, 1.001 * h, 0.5 * h, 2 * h, 0.0, std::numeric_limits<double>::infinity()})
      EXPECT_EQ(within(limit), h <= limit) << "limit " << limit << ", distance " << h;
  };
  for (const mm::Mesh* other : {&bumped, &big}) {
    const double h = mm::surface_distance(s, *other, fast()).hausdorff_relative();
    check(h, [&](double limit) { return mm::surface_within(part, *other, limit); });
  }
  const double h = mm::decoded_distance(s, control, 2, fast()).hausdorff_relative();
  check(h, [&](double limit) { return mm::decoded_within(part, control, 2, limit); });
  // Bad input fails as a measurement does.
  mm::Mesh flat = control;
  flat.points.setZero();
  EXPECT_THROW(mm::surface_within(part, flat, 1.0), mm::InputError);
}

// A part measured once against many surfaces (MeasuredSurface): every measurement gives the
// numbers of a fresh one, in any order, early-stopped ones between them, and from threads at
// once; a bad part fails at its first measurement, as surface_distance does, and again after.
TEST(SurfaceDistance, APartMeasuredOnceGivesEachMeasurementsOwnNumbers) {
  const Sphere x;
  const mm::Mesh &s = x.part, &bumped = x.bumped, &big = x.big, &control = x.control;
  const mm::MeasuredSurface part(s, fast());
  const mm::SurfaceDistance fresh_bumped = mm::surface_distance(s, bumped, fast());
  const mm::SurfaceDistance fresh_big = mm::surface_distance(s, big, fast());
  const mm::SurfaceDistance fresh_decoded = mm::decoded_distance(s, control, 2, fast());
  const auto same = [](const mm::SurfaceDistance& a, const mm::SurfaceDistance& b) {
    return a.hausdorff == b.hausdorff && a.rms == b.rms && a.mean == b.mean && a.a_to_b.max == b.a_to_b.max &&
           a.b_to_a.mean == b.b_to_a.mean && a.diagonal == b.diagonal;
  };
  for (int pass = 0; pass < 2; ++pass) {
    auto d = mm::surface_distance_within(part, big, std::numeric_limits<double>::infinity());
    ASSERT_TRUE(d.has_value());
    EXPECT_TRUE(same(*d, fresh_big));
    EXPECT_FALSE(mm::surface_distance_within(part, big, 0.5 * fresh_big.hausdorff_relative()).has_value());
    d = mm::surface_distance_within(part, bumped, fresh_bumped.hausdorff_relative());
    ASSERT_TRUE(d.has_value());
    EXPECT_TRUE(same(*d, fresh_bumped));
    EXPECT_TRUE(same(mm::decoded_distance(part, control, 2), fresh_decoded));
  }
  // The same triangles moved (a control polyhedron's stream at another grid) are measured on the
  // tree layout of the surface before them (MeasuredSurface remembers it): their own numbers.
  mm::Mesh moved = control;
  moved.points *= 1.01;
  moved.points.row(0) *= 1.05;
  const mm::SurfaceDistance fresh_moved = mm::decoded_distance(s, moved, 2, fast());
  ASSERT_NE(fresh_moved.hausdorff, fresh_decoded.hausdorff);
  EXPECT_TRUE(same(mm::decoded_distance(part, moved, 2), fresh_moved));
  EXPECT_TRUE(mm::decoded_within(part, moved, 2, fresh_moved.hausdorff_relative()));
  EXPECT_FALSE(mm::decoded_within(part, moved, 2, std::nextafter(fresh_moved.hausdorff_relative(), 0.0)));
  EXPECT_TRUE(same(mm::decoded_distance(part, control, 2), fresh_decoded));
  // A measured part queries its samples along a curve through space (sample_order), one
  // measured plainly in index order: the same numbers.
  const mm::OneSidedDistance plain = mm::one_sided_distance(s, big, fast());
  EXPECT_EQ(plain.max, fresh_big.a_to_b.max);
  EXPECT_EQ(plain.mean, fresh_big.a_to_b.mean);
  EXPECT_EQ(plain.rms, fresh_big.a_to_b.rms);
  std::vector<int> sorted = part.sample_order();
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t i = 0; i < sorted.size(); ++i) ASSERT_EQ(sorted[i], static_cast<int>(i));
  EXPECT_NE(part.sample_order(), sorted);
  // Shared by threads, its first measurement among them.
  const mm::MeasuredSurface shared(s, fast());
  std::vector<mm::SurfaceDistance> got(4);
  std::vector<std::thread> threads;
  for (std::size_t t = 0; t < got.size(); ++t)
    threads.emplace_back([&, t] { got[t] = mm::decoded_distance(shared, control, 2); });
  for (auto& t : threads) t.join();
  for (const auto& d : got) EXPECT_TRUE(same(d, fresh_decoded));
  mm::Mesh line = cube();
  line.points.col(2).setZero();
  line.points.col(1).setZero();  // no area anywhere
  const mm::MeasuredSurface bad(line, fast());
  EXPECT_THROW(mm::decoded_distance(bad, control, 2), mm::InputError);
  EXPECT_THROW(mm::decoded_distance(bad, control, 2), mm::InputError);
}
