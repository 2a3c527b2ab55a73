// The resynchronisation context builds its levels on first use: a suspect builds only the level
// its vertex count names (and the one below) or the fit surface, the results are those of a
// context built in full, concurrent first uses build a level once, and the context's own byte
// count follows the heap.
#include <gtest/gtest.h>
#include <malloc.h>

#include <cstddef>
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
// The sanitizer runtimes' own counter (declared here: GCC ships no header for it).
extern "C" std::size_t __sanitizer_get_current_allocated_bytes();
#define MM_SANITIZED_HEAP 1
#else
#define MM_SANITIZED_HEAP 0
#endif

#include <Eigen/Geometry>
#include <algorithm>
#include <map>
#include <random>
#include <thread>
#include <tuple>

#include "common/shared_meshes.h"
#include "common/shuffled_mesh.h"
#include "fitting/sharp_features.h"
#include "meshio/normalize.h"
#include "meshio/read_mesh.h"
#include "registration/resynchronize.h"
#include "registration/remesh.h"
#include "subdivision/decompress.h"
#include "subdivision/subdivide.h"

namespace {

using mm::Mesh;
using mm::Points;
using mm::ResyncContext;
using mm::Resynchronized;

// fandisk_quads with its sharp edges tagged, as compress() makes control polyhedra: levels then
// carry the re-subdivided hypothesis, whose level L needs level L-1.
Mesh creased_fandisk() {
  Mesh m = mm::read_mesh(mm::test::shared_mesh("fandisk_quads.off"));
  mm::apply(mm::unit_box_normalization(m.points), m.points);
  const mm::Features f = mm::detect_features(m);
  m.creases = f.sharp_edges;
  m.corners = f.corners;
  return m;
}

void add_noise(Mesh& m, double amplitude, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-amplitude, amplitude);
  for (Eigen::Index i = 0; i < m.points.rows(); ++i)
    for (int c = 0; c < 3; ++c) m.points(i, c) += u(rng);
}

void moved(Mesh& m) {
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  for (Eigen::Index i = 0; i < m.points.rows(); ++i)
    m.points.row(i) = 3.0 * (R * m.points.row(i).transpose()).transpose() + Eigen::RowVector3d(10, -4, 2);
}

void expect_identical(const Resynchronized& a, const Resynchronized& b, const std::string& what) {
  EXPECT_EQ(a.method, b.method) << what;
  EXPECT_EQ(a.level, b.level) << what;
  EXPECT_EQ(a.order_recovered, b.order_recovered) << what;
  EXPECT_EQ(a.resubdivided, b.resubdivided) << what;
  ASSERT_EQ(a.points.rows(), b.points.rows()) << what;
  EXPECT_EQ((a.points - b.points).cwiseAbs().maxCoeff(), 0.0) << what;  // bit for bit
  EXPECT_EQ(a.residual_rms, b.residual_rms) << what;
  EXPECT_EQ(a.matched_fraction, b.matched_fraction) << what;
}

struct Case {
  std::string name;
  Mesh suspect;
  std::vector<int> built;  // levels a fresh context has built after this suspect
  bool fit = false;        // whether it needed the fit surface
};

// Heap bytes in use (small chunks in the arena and large mmap'ed blocks). Sanitizers replace
// glibc's allocator, whose counters then stay still: ask theirs.
std::size_t heap_in_use() {
#if MM_SANITIZED_HEAP
  return __sanitizer_get_current_allocated_bytes();
#else
  const struct mallinfo2 mi = mallinfo2();
  return mi.uordblks + mi.hblkhd;
#endif
}

}  // namespace

TEST(ResyncContext, LazyLevelsGiveTheResultsOfAFullyBuiltContext) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh control = creased_fandisk();
  ASSERT_FALSE(control.creases.empty());
  const ResyncContext full(control, 3);
  full.build_all();
  for (int l = 0; l <= 3; ++l) EXPECT_TRUE(full.level_built(l));

  Mesh marked = control;
  add_noise(marked, 0.002, 5);  // stands in for a mark: the control points move
  Mesh polyhedron = marked;
  add_noise(polyhedron, 0.0005, 6);
  Mesh in_order = mm::subdivide(marked, 2);
  moved(in_order);
  Mesh noisy_shuffled = mm::test::shuffled(mm::subdivide(marked, 2), 3);
  add_noise(noisy_shuffled, 0.0005, 7);
  Mesh decoded = mm::subdivide(marked, 1);  // a decoded file: no tags, refined once more
  decoded.creases.clear();
  decoded.corners.clear();
  const Mesh resubdivided = mm::subdivide(decoded, 1);
  const Mesh remeshed = mm::test::decimate(mm::subdivide(marked, 2), 3000);

  std::vector<Case> cases;
  cases.push_back({"polyhedron", polyhedron, {0}});
  cases.push_back({"subdivided 2, moved", in_order, {0, 1, 2}});
  cases.push_back({"subdivided 2, shuffled, noisy", noisy_shuffled, {0, 1, 2}});
  cases.push_back({"level 1 refined without tags", resubdivided, {0, 1, 2}});
  cases.push_back({"remeshed", remeshed, {0, 1, 2, 3}, true});  // fit level 3 needs 0..3
  std::map<std::string, Resynchronized> got;
  for (const Case& c : cases) {
    const ResyncContext lazy(control, 3);
    const std::size_t before = lazy.memory_bytes();
    const Resynchronized r = mm::resynchronize(lazy, c.suspect);
    for (int l = 0; l <= 3; ++l)
      EXPECT_EQ(lazy.level_built(l), std::find(c.built.begin(), c.built.end(), l) != c.built.end())
          << c.name << ", level " << l;
    EXPECT_GE(lazy.memory_bytes(), before) << c.name;
    if (!c.fit) {
      EXPECT_LT(lazy.memory_bytes(), full.memory_bytes() / 2) << c.name;
    }
    expect_identical(r, mm::resynchronize(full, c.suspect), c.name);
    got[c.name] = r;
  }
  // What the cases were recognised as (so the comparison covers every path).
  EXPECT_EQ(got["polyhedron"].method, "polyhedron");
  EXPECT_EQ(got["subdivided 2, moved"].level, 2);
  EXPECT_TRUE(got["subdivided 2, shuffled, noisy"].order_recovered);
  EXPECT_TRUE(got["level 1 refined without tags"].resubdivided);
  EXPECT_EQ(got["remeshed"].method, "surface-fit");
  // Public accessors build what they are asked for; counts are known without building.
  const ResyncContext fresh(control, 3);
  EXPECT_FALSE(fresh.level_built(3));
  EXPECT_EQ(fresh.vertex_count(3), full.refined_points(3).rows());
  EXPECT_FALSE(fresh.level_built(3));
  EXPECT_EQ(fresh.subdivision(3).S.rows(), full.subdivision(3).S.rows());
  EXPECT_TRUE(fresh.level_built(3));
  EXPECT_THROW(fresh.subdivision(4), std::out_of_range);
  EXPECT_THROW(fresh.vertex_count(-1), std::out_of_range);
}

TEST(ResyncContext, ConcurrentFirstUsesBuildALevelOnce) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh control = creased_fandisk();
  Mesh marked = control;
  add_noise(marked, 0.002, 5);
  Mesh suspect = mm::subdivide(marked, 3);
  moved(suspect);

  const ResyncContext alone(control, 3);
  const Resynchronized expected = mm::resynchronize(alone, suspect);

  const ResyncContext shared(control, 3);
  constexpr int kThreads = 4;
  std::vector<Resynchronized> results(kThreads);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&, t] { results[static_cast<size_t>(t)] = mm::resynchronize(shared, suspect); });
  for (auto& t : threads) t.join();
  for (int t = 0; t < kThreads; ++t) expect_identical(results[static_cast<size_t>(t)], expected, "thread " + std::to_string(t));
  // Every build adds its bytes: a level built twice would count twice.
  EXPECT_EQ(shared.memory_bytes(), alone.memory_bytes());
}

TEST(ResyncContext, MemoryBytesFollowTheHeap) {
  MM_REQUIRE_SHARED_MESHES();
  const Mesh quads = creased_fandisk();
  // All triangles (Loop rows, one fit triangle per refined face), as compress() makes of STL parts.
  Mesh tri = mm::triangulate(quads);
  const mm::Features tf = mm::detect_features(tri);
  tri.creases = tf.sharp_edges;
  tri.corners = tf.corners;
  const Mesh& triangles = tri;
  for (const auto& [name, control, top] :
       {std::tuple{"quads", &quads, 2}, std::tuple{"quads", &quads, 3}, std::tuple{"quads", &quads, 4},
        std::tuple{"triangles", &triangles, 3}}) {
    const std::size_t heap0 = heap_in_use();
    auto ctx = std::make_unique<ResyncContext>(*control, top);
    ctx->build_all();
    const double heap = static_cast<double>(heap_in_use() - heap0);
    const double own = static_cast<double>(ctx->memory_bytes());
    std::printf("%s, levels 0..%d: memory_bytes %.1f MB, heap %.1f MB (ratio %.3f)\n", name, top, own / 1e6,
                heap / 1e6, own / heap);
    EXPECT_GT(own, 0.9 * heap) << name << ", levels 0.." << top;
    EXPECT_LT(own, 1.1 * heap) << name << ", levels 0.." << top;
    ctx.reset();
  }
}
