// fit_part / compress_part: the one compression entry point of `meshmark compress` and protect
// jobs. The fits do not depend on how they were run; fallback angles are fitted only while no
// fit meets the tolerance; a protect job keeps the first fit that met it, else the closest.
#include <gtest/gtest.h>

#include <algorithm>

#include "compression/compress_part.h"
#include "samples/samples.h"

namespace mm {
namespace {

// A tolerance the coarse flanged cylinder below meets only split.
constexpr double kSplitTolerance = 0.002;

const Mesh& part() {
  static const Mesh m = samples::sample_parts().at(0).mesh;
  return m;
}

TEST(CompressPart, FitsAreTheSameWhicheverOrderTheyRunIn) {
  const MeasuredSurface measured(part());
  PartOptions o;
  o.angles = {35.0, 45.0, 55.0};
  const PartFits in_order = fit_part(part(), measured, o, "part");
  // A runner that starts the last task first, as threads may.
  int calls = 0;
  o.at_once = 3;
  o.parallel = [&calls](int n, int, const std::function<void(int)>& task) {
    ++calls;
    for (int k = n - 1; k >= 0; --k) task(k);
  };
  const PartFits reversed = fit_part(part(), measured, o, "part");
  EXPECT_GE(calls, in_order.fits.size() > 1 ? 1 : 0);
  ASSERT_EQ(in_order.fits.size(), reversed.fits.size());
  for (std::size_t k = 0; k < in_order.fits.size(); ++k) {
    EXPECT_EQ(in_order.fits[k].angle, reversed.fits[k].angle);
    EXPECT_TRUE(in_order.fits[k].result.control.points == reversed.fits[k].result.control.points) << k;
  }
  ASSERT_EQ(in_order.polyhedra.size(), reversed.polyhedra.size());
  EXPECT_TRUE(std::is_sorted(in_order.polyhedra.begin(), in_order.polyhedra.end(), [](const auto& a, const auto& b) {
    return a.second->num_vertices() < b.second->num_vertices();
  }));
}

TEST(CompressPart, FallbackAnglesAreFittedOnlyWhileNothingMeetsTheTolerance) {
  const MeasuredSurface measured(part());
  PartOptions met;
  met.fallback_angles = {30.0, 25.0, 20.0};
  const PartFits a = fit_part(part(), measured, met, "part");
  ASSERT_TRUE(a.fits.front().result.tolerance_met);
  EXPECT_EQ(a.fits.size(), 1u);
  EXPECT_EQ(&a.kept(), &a.fits.front());

  PartOptions missed = met;
  missed.fit.max_vertices = 12;  // fewer than the part's 24 corners: every angle refuses it
  EXPECT_THROW(fit_part(part(), measured, missed, "part"), InputError);
  missed.fit.tolerance = 1e-5;  // out of reach of 30 control vertices (a chamfer stays rounded)
  missed.fit.max_vertices = 30;
  const PartFits b = fit_part(part(), measured, missed, "part");
  EXPECT_FALSE(std::any_of(b.fits.begin(), b.fits.end(), [](const FitAtAngle& f) { return f.result.tolerance_met; }));
  EXPECT_TRUE(b.polyhedra.empty());
  // The block's chamfers are 45-degree folds: 30, 25 and 20 find 35's crease network, which is
  // not fitted again.
  EXPECT_EQ(b.fits.size(), 1u);
  EXPECT_TRUE(b.refused.empty());
  const FitAtAngle& kept = b.kept();
  for (const auto& f : b.fits)
    EXPECT_LE(kept.result.stats.hausdorff / kept.result.stats.diagonal,
              f.result.stats.hausdorff / f.result.stats.diagonal);
}

TEST(CompressPart, TheStreamIsSearchedAmongThePolyhedraThatMetTheTolerance) {
  const MeasuredSurface measured(part());
  PartOptions o;
  o.stream.quick = true;
  const CompressedPart c = compress_part(part(), measured, o, "part");
  ASSERT_NE(c.control, nullptr);
  ASSERT_NE(c.fit, nullptr);
  EXPECT_TRUE(c.stream.meets);
  EXPECT_FALSE(c.stream.bytes.empty());
  EXPECT_EQ(c.candidates, static_cast<int>(c.fits.polyhedra.size()));
  EXPECT_EQ(c.control, c.fits.polyhedra.front().second);  // quick: the fewest vertices that met it
}

// Out of reach, the stream is the closest fit's (the one fitted on to the budget), whichever
// angle it was fitted at: the first angle's rounds stopped earlier.
TEST(CompressPart, AMissedToleranceWritesTheClosestFit) {
  const MeasuredSurface measured(part());
  PartOptions o;
  o.angles = {35.0, 50.0};
  o.fit.tolerance = 1e-5;  // out of reach of 30 control vertices (as above)
  o.fit.max_vertices = 30;
  o.stream.quick = true;
  const CompressedPart c = compress_part(part(), measured, o, "part");
  ASSERT_TRUE(c.fits.polyhedra.empty());
  ASSERT_GT(c.fits.fits.size(), 1u);
  ASSERT_NE(&c.fits.kept(), &c.fits.fits.front());  // the extended fit went to the back
  EXPECT_EQ(c.fit, &c.fits.kept());
  EXPECT_EQ(c.control, &c.fits.kept().result.control);
  EXPECT_TRUE(stopped_at_budget(c.fit->result, o.fit)) << tolerance_miss_reason(c.fit->result, o.fit);
}

TEST(CompressPart, CoarseTessellationIsSplitWhenItsVerticesRunOut) {
  // Twelve sectors: 30-degree facets, smooth to a 35-degree crease angle, which a subdivision
  // surface through the part's own vertices rounds off by more than the tolerance.
  samples::FlangedCylinder p;
  p.sectors = 12;
  p.edge_length = 6;
  const Mesh coarse = samples::flanged_cylinder(p);
  const MeasuredSurface measured(coarse);
  PartOptions o;
  o.fit.tolerance = kSplitTolerance;
  o.fit.max_vertices = 20000;
  o.max_splits = 0;
  const PartFits whole = fit_part(coarse, measured, o, "coarse");
  ASSERT_TRUE(whole.polyhedra.empty());
  const CompressResult& r = whole.kept().result;
  EXPECT_TRUE(r.all_vertices);
  EXPECT_EQ(r.control.num_vertices(), coarse.num_vertices());
  EXPECT_EQ(tolerance_miss_reason(r, o.fit), "with every vertex of the part (" + std::to_string(coarse.num_vertices()) +
                                                 ") as a control vertex, under the budget of 20000");

  o.max_splits = 2;
  const PartFits split = fit_part(coarse, measured, o, "coarse");
  ASSERT_FALSE(split.polyhedra.empty());
  EXPECT_GE(split.kept().result.part_splits, 1);
  EXPECT_GT(split.kept().result.control.num_vertices(), coarse.num_vertices());
  // Met by the dense measurement against the part as given, not its split.
  EXPECT_TRUE(decoded_within(measured, *split.polyhedra.front().second, o.fit.levels, o.fit.tolerance));

  // A budget the part's own vertices already fill: no split.
  o.fit.max_vertices = coarse.num_vertices();
  const PartFits capped = fit_part(coarse, measured, o, "coarse");
  EXPECT_EQ(capped.kept().result.part_splits, 0);
}

}  // namespace
}  // namespace mm
