// descended_on_grid(): grid values chosen for the subdivided surface. Checked against the
// nearest grid values on a fitted polyhedron of a sample part (no shared meshes needed).
#include <gtest/gtest.h>

#include "codec/quantize.h"
#include "codec/stream.h"
#include "fitting/compress.h"
#include "compression/grid_descent.h"
#include "samples/samples.h"
#include "subdivision/subdivide.h"

namespace {

const mm::Mesh& fitted_block() {
  static const mm::Mesh control = mm::compress(mm::samples::sample_parts().at(0).mesh).control;
  return control;
}

// The objective descended_on_grid lowers: refined vertices' squared offsets from the
// unquantised polyhedron's.
double refined_offset2(const mm::Mesh& control, const mm::Points& points) {
  const mm::SubdivisionOperator op = mm::build_subdivision(control, 3);
  return (op.S * (points - control.points)).squaredNorm();
}

}  // namespace

TEST(GridDescent, RefinedSurfaceCloserThanWithNearestValuesAndCodedExactly) {
  const mm::Mesh& control = fitted_block();
  int closer = 0;
  for (int bits : {6, 7, 8, 10}) {
    SCOPED_TRACE(bits);
    const mm::Quantization q = mm::quantization_for(control.points, bits);
    const mm::GridPoints nearest = mm::quantize(control.points, q);
    const mm::Mesh d = mm::descended_on_grid(control, bits, 3);
    const double rounded = refined_offset2(control, mm::dequantize(nearest, q));
    const double descended = refined_offset2(control, d.points);
    EXPECT_LE(descended, rounded);
    closer += descended < 0.99 * rounded;
    // The same grid (extremes untouched), and the encoder codes the chosen values exactly.
    mm::CodecParams p;
    p.quant_bits = bits;
    const mm::DecodedStream back = mm::decode(mm::encode(d, p), "descended");
    EXPECT_EQ(back.quantization.step, q.step);
    EXPECT_EQ(back.quantization.offset, q.offset);
    EXPECT_TRUE(back.mesh.points == d.points);
    EXPECT_EQ(back.grid.colwise().minCoeff(), nearest.colwise().minCoeff());
    EXPECT_EQ(back.grid.colwise().maxCoeff(), nearest.colwise().maxCoeff());
    // Only the points change, and the same input gives the same values.
    EXPECT_EQ(d.faces, control.faces);
    EXPECT_EQ(d.creases, control.creases);
    EXPECT_EQ(d.corners, control.corners);
    EXPECT_TRUE(mm::descended_on_grid(control, bits, 3).points == d.points);
  }
  EXPECT_GE(closer, 2);  // a real change on the coarse grids, not the nearest values again
}
