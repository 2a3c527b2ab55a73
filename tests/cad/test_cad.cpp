// STEP and IGES parts through OpenCASCADE: the tessellation is a closed, outward, deterministic
// mesh of the solid within its deflection; bad files are refused naming the file.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <iterator>
#include <map>
#include <utility>

#include "cad/read_part.h"
#include "cad/sample_solids.h"
#include "cad/tessellate.h"

namespace mm {
namespace {

// Drilled block: 40 x 30 x 20 less a radius-6 bore through 20 and a radius-3 hole through 30.
const double kDrilledVolume = 40.0 * 30 * 20 - M_PI * 36 * 20 - M_PI * 9 * 30;

double signed_volume(const Mesh& m) {
  double v = 0;
  for (const auto& f : m.faces) {
    const Eigen::Vector3d a = m.points.row(f[0]), b = m.points.row(f[1]), c = m.points.row(f[2]);
    v += a.dot(b.cross(c)) / 6;
  }
  return v;
}

// Every directed edge used once and its reverse once: closed and consistently oriented.
bool closed_and_oriented(const Mesh& m) {
  std::map<std::pair<int, int>, int> directed;
  for (const auto& f : m.faces)
    for (std::size_t k = 0; k < f.size(); ++k) ++directed[{f[k], f[(k + 1) % f.size()]}];
  for (const auto& [e, n] : directed) {
    if (n != 1) return false;
    const auto r = directed.find({e.second, e.first});
    if (r == directed.end() || r->second != 1) return false;
  }
  return true;
}

TEST(CadSamples, AreTheSameBytesOnEveryCall) {
  for (const char* format : {"step", "iges"}) {
    const std::string a = cad::sample_solid_bytes("drilled_block", format);
    EXPECT_GT(a.size(), 1000u) << format;
    EXPECT_TRUE(a == cad::sample_solid_bytes("drilled_block", format)) << format;
    if (std::string(format) == "step") EXPECT_NE(a.find("PRODUCT('drilled_block'"), std::string::npos);
  }
  EXPECT_THROW(cad::sample_solid_bytes("no_such_part", "step"), std::invalid_argument);
  EXPECT_THROW(cad::sample_solid_bytes("drilled_block", "stl"), std::invalid_argument);
}

TEST(Tessellate, StepAndIgesGiveAClosedOutwardMeshOfTheSolid) {
  for (const char* format : {"step", "iges"}) {
    Tessellation info;
    const Mesh m = tessellate_cad(cad::sample_solid_bytes("drilled_block", format), format, "block", {}, &info);
    EXPECT_EQ(info.format, format);
    EXPECT_EQ(info.solids, 1) << format;
    EXPECT_EQ(info.faces, 8) << format;  // 6 sides, the bore, the side hole
    EXPECT_EQ(info.occt_version, occt_version());
    EXPECT_TRUE(closed_and_oriented(m)) << format;
    // Chords of the holes' circles lie inside the solid's surface: the mesh's volume is a little
    // larger, by at most the deflection times the holes' area.
    const double v = signed_volume(m);
    EXPECT_GT(v, kDrilledVolume) << format;
    EXPECT_LT(v, kDrilledVolume * 1.01) << format;
    const Eigen::Vector3d lo = m.points.colwise().minCoeff(), hi = m.points.colwise().maxCoeff();
    EXPECT_NEAR((hi - lo).norm(), std::sqrt(40.0 * 40 + 30 * 30 + 20 * 20), 1e-9) << format;
  }
}

TEST(Tessellate, IsDeterministicAndFinerDeflectionGivesMoreTrianglesCloserToTheSolid) {
  const std::string step = cad::sample_solid_bytes("drilled_block", "step");
  const Mesh a = tessellate_cad(step, "step", "block");
  const Mesh b = tessellate_cad(step, "stp", "block");
  ASSERT_EQ(a.points.rows(), b.points.rows());
  EXPECT_EQ(a.points, b.points);
  EXPECT_EQ(a.faces, b.faces);
  TessellationOptions fine;
  fine.linear_deflection = 0.00005;
  fine.angular_deflection_degrees = 5;
  Tessellation info;
  const Mesh f = tessellate_cad(step, "step", "block", fine, &info);
  EXPECT_GT(f.num_faces(), a.num_faces());
  EXPECT_LT(signed_volume(f) - kDrilledVolume, signed_volume(a) - kDrilledVolume);
  // The bounding box OpenCASCADE measures is enlarged by the shape's tolerance (1e-7 mm).
  EXPECT_NEAR(info.linear_deflection_mm, 0.00005 * std::sqrt(2900.0), 1e-9);
  EXPECT_NE(tessellation_key(fine), tessellation_key({}));
  // The options come back out of a preparation key that ends with the tessellation key, so an
  // evidence package tessellates the stored original as it was tessellated for the copy.
  const auto back = tessellation_options_in("tolerance=0.005;levels=3;" + tessellation_key(fine));
  ASSERT_TRUE(back);
  EXPECT_EQ(back->linear_deflection, fine.linear_deflection);
  EXPECT_EQ(back->angular_deflection_degrees, fine.angular_deflection_degrees);
  EXPECT_FALSE(tessellation_options_in("tolerance=0.005;levels=3"));
  EXPECT_FALSE(tessellation_options_in("occt=7.6.3;linear=x;angular=15"));
  EXPECT_FALSE(tessellation_options_in("occt=7.6.3;linear=-1;angular=15"));
}

TEST(Tessellate, SeveralSolidsInOneFileAreOnePart) {
  Tessellation info;
  const Mesh m = tessellate_cad(cad::sample_solid_bytes("block_pair", "step"), "step", "pair", {}, &info);
  EXPECT_EQ(info.solids, 2);
  EXPECT_TRUE(closed_and_oriented(m));
  EXPECT_NEAR(signed_volume(m), 2 * kDrilledVolume, 0.02 * kDrilledVolume);
}

TEST(Tessellate, BadFilesAreRefusedNamingTheFileAndTheReason) {
  const std::string step = cad::sample_solid_bytes("drilled_block", "step");
  const auto reason = [](const std::string& bytes, const std::string& format, const TessellationOptions& o = {}) {
    try {
      tessellate_cad(bytes, format, "suspect.step", o);
    } catch (const InputError& e) {
      EXPECT_EQ(e.source(), "suspect.step");
      return e.reason();
    }
    return std::string("accepted");
  };
  EXPECT_EQ(reason("", "step"), "empty file");
  EXPECT_NE(reason("ISO-10303-21;\nthis is not STEP\n", "step").find("STEP"), std::string::npos);
  EXPECT_NE(reason("not an IGES file at all", "iges").find("IGES"), std::string::npos);
  EXPECT_NE(reason(step.substr(0, step.size() / 3), "step"), "accepted");
  EXPECT_NE(reason(step, "stl").find("unknown CAD format"), std::string::npos);
  TessellationOptions bad;
  bad.linear_deflection = 0;
  EXPECT_NE(reason(step, "step", bad).find("linear deflection"), std::string::npos);
  bad = {};
  bad.angular_deflection_degrees = std::nan("");
  EXPECT_NE(reason(step, "step", bad).find("angular deflection"), std::string::npos);
}

// A STEP file whose oriented edge refers to itself makes OpenCASCADE recurse until its stack
// overflows (found by fuzz_cad): the reader's process dies, this one reports it and goes on.
TEST(Tessellate, AReaderThatCrashesIsAnInputErrorAndTheProcessGoesOn) {
  std::ifstream in(std::string(MESHMARK_SOURCE_DIR) + "/tests/fuzz/regressions/cad/step-oriented-edge-refers-to-itself",
                   std::ios::binary);
  ASSERT_TRUE(in);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  try {
    tessellate_cad(bytes.substr(1), "step", "hostile.step");  // the first byte is the fuzz target's format
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.source(), "hostile.step");
    EXPECT_NE(e.reason().find("OpenCASCADE crashed reading it"), std::string::npos) << e.reason();
  }
  EXPECT_GT(tessellate_cad(cad::sample_solid_bytes("drilled_block", "step"), "step", "block").num_faces(), 0);
}

TEST(ReadPart, TakesMeshAndCadFormatsByExtension) {
  EXPECT_TRUE(is_part_format("step"));
  EXPECT_TRUE(is_part_format("igs"));
  EXPECT_TRUE(is_part_format("stl"));
  EXPECT_FALSE(is_part_format("mmc"));
  EXPECT_NE(part_format_list().find("step"), std::string::npos);
  PartReport report;
  const Mesh m = parse_part(cad::sample_solid_bytes("drilled_block", "step"), "step", "block.step", {}, &report);
  EXPECT_GT(m.num_faces(), 0);
  EXPECT_EQ(report.read.format, "step");
  EXPECT_EQ(report.read.unit, "millimeter");
  ASSERT_TRUE(report.tessellation.has_value());
  EXPECT_EQ(report.tessellation->solids, 1);
  const Mesh off = parse_part("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "off", "t.off", {}, &report);
  EXPECT_EQ(off.num_faces(), 1);
  EXPECT_FALSE(report.tessellation.has_value());
  EXPECT_THROW(read_part("/nonexistent/part.step"), InputError);
}

}  // namespace
}  // namespace mm
