// The attack library: each attack does what it says, deterministically, and refuses what it
// cannot do with a clear error.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "attacks/crop.h"
#include "attacks/perturb.h"
#include "attacks/retessellate.h"
#include "quality/surface_distance.h"
#include "samples/samples.h"
#include "subdivision/decompress.h"

namespace {

mm::Mesh block() { return mm::samples::chamfered_block(); }

double diagonal(const mm::Mesh& m) { return (m.points.colwise().maxCoeff() - m.points.colwise().minCoeff()).norm(); }

// Every undirected edge has exactly two faces: a closed surface.
bool closed(const mm::Mesh& m) {
  std::map<std::pair<int, int>, int> count;
  for (const auto& f : m.faces)
    for (std::size_t k = 0; k < f.size(); ++k) {
      int a = f[k], b = f[(k + 1) % f.size()];
      ++count[{std::min(a, b), std::max(a, b)}];
    }
  return std::all_of(count.begin(), count.end(), [](const auto& e) { return e.second == 2; });
}

TEST(Attacks, NoiseIsBoundedAndSeeded) {
  const mm::Mesh m = block();
  mm::Points a = m.points, b = m.points, c = m.points;
  mm::attacks::add_uniform_noise(a, 0.01, 7);
  mm::attacks::add_uniform_noise(b, 0.01, 7);
  mm::attacks::add_uniform_noise(c, 0.01, 8);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
  const double side = mm::attacks::largest_side(m.points);
  EXPECT_LE((a - m.points).cwiseAbs().maxCoeff(), 0.01 * side);
  EXPECT_GT((a - m.points).cwiseAbs().maxCoeff(), 0.009 * side);
}

TEST(Attacks, QuantisationPutsEveryCoordinateAtACellCentre) {
  const mm::Mesh m = block();
  mm::Points q = m.points;
  mm::attacks::quantize_coordinates(q, 6);
  const double step = mm::attacks::largest_side(m.points) / 64;
  const Eigen::RowVector3d low = m.points.colwise().minCoeff();
  EXPECT_LE((q - m.points).cwiseAbs().maxCoeff(), step / 2 + 1e-12);
  for (Eigen::Index i = 0; i < q.rows(); ++i)
    for (int k = 0; k < 3; ++k) {
      const double cells = (q(i, k) - low[k]) / step - 0.5;
      EXPECT_NEAR(cells, std::round(cells), 1e-9);
    }
  EXPECT_THROW(mm::attacks::quantize_coordinates(q, 0), std::invalid_argument);
}

TEST(Attacks, SmoothingShrinksAndKeepsConnectivity) {
  mm::Mesh m = block();
  const mm::Mesh before = m;
  mm::attacks::smooth_laplacian(m, 10, 0.5);
  EXPECT_EQ(m.faces, before.faces);
  const Eigen::RowVector3d centre = before.points.colwise().mean();
  auto spread = [&](const mm::Points& p) { return (p.rowwise() - centre).rowwise().norm().mean(); };
  EXPECT_LT(spread(m.points), spread(before.points));
  mm::Mesh none = before;
  mm::attacks::smooth_laplacian(none, 0, 0.5);
  EXPECT_EQ(none.points, before.points);
  EXPECT_THROW(mm::attacks::smooth_laplacian(m, 1, 0.0), std::invalid_argument);
}

TEST(Attacks, ReorderKeepsTheSurface) {
  const mm::Mesh m = block();
  mm::Mesh r = m;
  mm::attacks::shuffle_order(r, 5);
  mm::Mesh again = m;
  mm::attacks::shuffle_order(again, 5);
  EXPECT_EQ(r.points, again.points);
  EXPECT_EQ(r.faces, again.faces);
  EXPECT_NE(r.points, m.points);
  // The same faces as coordinate lists up to their starting vertex.
  auto faces_as_points = [](const mm::Mesh& mesh) {
    std::multiset<std::vector<double>> out;
    for (const auto& f : mesh.faces) {
      std::vector<std::vector<double>> corners;
      for (int v : f) corners.push_back({mesh.points(v, 0), mesh.points(v, 1), mesh.points(v, 2)});
      std::rotate(corners.begin(), std::min_element(corners.begin(), corners.end()), corners.end());
      std::vector<double> flat;
      for (const auto& c : corners) flat.insert(flat.end(), c.begin(), c.end());
      out.insert(flat);
    }
    return out;
  };
  EXPECT_EQ(faces_as_points(r), faces_as_points(m));
}

TEST(Attacks, AverageIsTheMeanAndRefusesOtherConnectivity) {
  const mm::Mesh m = block();
  mm::Mesh a = m, b = m;
  mm::attacks::add_uniform_noise(a.points, 0.01, 1);
  mm::attacks::add_uniform_noise(b.points, 0.01, 2);
  const mm::Mesh mean = mm::attacks::average_copies({a, b}, {"a.off", "b.off"});
  EXPECT_LE(((a.points + b.points) / 2 - mean.points).cwiseAbs().maxCoeff(), 1e-12);
  const mm::Mesh cropped = mm::attacks::crop_along_longest_axis(m, 0.5);
  try {
    mm::attacks::average_copies({a, cropped}, {"a.off", "cropped.off"});
    FAIL() << "averaged copies of different connectivity";
  } catch (const mm::InputError& e) {
    EXPECT_EQ(e.source(), "cropped.off");
  }
}

TEST(Attacks, CropKeepsTheFacesOnOneSide) {
  const mm::Mesh m = block();
  const Eigen::RowVector3d low = m.points.colwise().minCoeff(), high = m.points.colwise().maxCoeff();
  Eigen::Index axis = 0;
  (high - low).maxCoeff(&axis);
  for (bool from_high : {false, true}) {
    const mm::Mesh c = mm::attacks::crop_along_longest_axis(m, 0.4, from_high);
    EXPECT_GT(c.num_faces(), 0);
    EXPECT_LT(c.num_faces(), m.num_faces() * 3 / 4);
    const double cut = from_high ? high[axis] - 0.4 * (high[axis] - low[axis]) : low[axis] + 0.4 * (high[axis] - low[axis]);
    for (const auto& f : c.faces) {
      double centroid = 0;
      for (int v : f) centroid += c.points(v, axis);
      centroid /= static_cast<double>(f.size());
      if (from_high) EXPECT_GE(centroid, cut);
      else EXPECT_LE(centroid, cut);
    }
    std::vector<bool> used(static_cast<std::size_t>(c.num_vertices()), false);
    for (const auto& f : c.faces)
      for (int v : f) used[static_cast<std::size_t>(v)] = true;
    EXPECT_TRUE(std::all_of(used.begin(), used.end(), [](bool u) { return u; }));
  }
  // A tetrahedron whose faces all lie away from its lowest x: a sliver keeps none of them.
  mm::Mesh tetra;
  tetra.points.resize(4, 3);
  tetra.points << 0, 0, 0, 2, 0, 0, 1, 1, 0, 1, 0, 1;
  tetra.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  EXPECT_THROW(mm::attacks::crop_along_longest_axis(tetra, 0.01), mm::InputError);
}

TEST(Attacks, RemeshingMakesEdgesOfTheAskedLengthOnTheSameSurface) {
  const mm::Mesh m = block();
  const mm::Mesh r = mm::attacks::remesh_isotropic(m, 0.02);
  const mm::Mesh again = mm::attacks::remesh_isotropic(m, 0.02);
  EXPECT_EQ(r.points, again.points);
  EXPECT_TRUE(closed(r));
  std::vector<double> lengths;
  for (const auto& [i, j] : mm::unique_edges(r)) lengths.push_back((r.points.row(i) - r.points.row(j)).norm());
  std::nth_element(lengths.begin(), lengths.begin() + static_cast<long>(lengths.size() / 2), lengths.end());
  const double median = lengths[lengths.size() / 2] / diagonal(m);
  EXPECT_GT(median, 0.01);
  EXPECT_LT(median, 0.03);
  EXPECT_LT(mm::surface_distance(m, r).hausdorff_relative(), 0.01);
}

TEST(Attacks, SimplificationKeepsTheAskedShareOfEdges) {
  const mm::Mesh m = mm::samples::flanged_cylinder();
  const mm::Mesh s = mm::attacks::simplify_edges(m, 0.2);
  const double kept = static_cast<double>(mm::unique_edges(s).size()) /
                      static_cast<double>(mm::unique_edges(mm::triangulate(m)).size());
  EXPECT_LT(kept, 0.25);
  EXPECT_TRUE(closed(s));
  EXPECT_LT(mm::surface_distance(m, s).hausdorff_relative(), 0.05);
}

TEST(Attacks, AlphaWrapEnclosesThePartCloselyAndIsClosed) {
  const mm::Mesh m = block();
  const mm::Mesh w = mm::attacks::alpha_wrap(m, 0.02, 0.002);
  EXPECT_TRUE(closed(w));
  EXPECT_LT(mm::surface_distance(m, w).hausdorff_relative(), 0.02);
  EXPECT_THROW(mm::attacks::alpha_wrap(m, 0, 0.1), std::invalid_argument);
}

}  // namespace
