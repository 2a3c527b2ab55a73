// 3MF through lib3mf: what write_mesh writes reads back (float32 positions, triangles, unit),
// every build item of a model is read with its and its components' transforms applied, and
// damaged or empty packages are refused by name.
#include <Model/COM/NMR_DLLInterfaces.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <vector>

#include "common/temp_dir.h"
#include "format_fixtures.h"
#include "meshio/read_mesh.h"

namespace mm {
namespace {

namespace fs = std::filesystem;

TEST(ThreeMf, WrittenMeshReadsBackAsFloatTrianglesInItsUnit) {
  const fs::path dir = test::scratch_dir("mm_3mf");
  const Mesh m = test::quad_and_triangle();
  for (const char* unit : {"", "inch", "micron"}) {
    const std::string path = (dir / (std::string("part-") + unit + ".3mf")).string();
    write_mesh(m, path, WriteOptions{unit});
    ReadReport report;
    const Mesh back = read_mesh(path, &report);
    EXPECT_EQ(report.format, "3mf");
    EXPECT_EQ(report.unit, *unit ? unit : "millimeter");
    EXPECT_EQ(report.objects, 1);
    ASSERT_EQ(back.num_vertices(), m.num_vertices());
    for (int i = 0; i < m.num_vertices(); ++i)
      for (int k = 0; k < 3; ++k) EXPECT_EQ(back.points(i, k), static_cast<double>(static_cast<float>(m.points(i, k))));
    // The quad is fanned into two triangles with its orientation.
    const std::vector<std::vector<int>> faces{{0, 1, 2}, {0, 2, 3}, {3, 2, 4}};
    EXPECT_EQ(back.faces, faces);
  }
  EXPECT_THROW(write_mesh(m, (dir / "bad-unit.3mf").string(), WriteOptions{"furlong"}), InputError);
  EXPECT_FALSE(fs::exists(dir / "bad-unit.3mf"));
}

// A model as a slicer writes one: a tetrahedron mesh object placed twice by build items (one
// rotated 90 degrees about z and moved), and a components object that places it once more,
// moved, inside a build item moved again.
TEST(ThreeMf, EveryBuildItemIsReadWithItsTransforms) {
  using namespace NMR;
  PLib3MFModel* model = nullptr;
  ASSERT_EQ(lib3mf_createmodel(&model), LIB3MF_OK);
  PLib3MFModelMeshObject* tet = nullptr;
  ASSERT_EQ(lib3mf_model_addmeshobject(model, &tet), LIB3MF_OK);
  MODELMESHVERTEX v[4] = {{{0, 0, 0}}, {{1, 0, 0}}, {{0, 1, 0}}, {{0, 0, 1}}};
  MODELMESHTRIANGLE t[4] = {{{0, 2, 1}}, {{0, 1, 3}}, {{0, 3, 2}}, {{1, 2, 3}}};
  ASSERT_EQ(lib3mf_meshobject_setgeometry(tet, v, 4, t, 4), LIB3MF_OK);
  auto identity = [] {
    MODELTRANSFORM m{};
    for (int i = 0; i < 3; ++i) m.m_fFields[i][i] = 1;
    return m;
  };
  PLib3MFModelBuildItem* item = nullptr;
  ASSERT_EQ(lib3mf_model_addbuilditem(model, tet, nullptr, &item), LIB3MF_OK);
  lib3mf_release(item);
  // x' = -y + 10, y' = x + 20, z' = z + 30 (row i of the fields gives coordinate i).
  MODELTRANSFORM rotated{};
  rotated.m_fFields[0][1] = -1;
  rotated.m_fFields[1][0] = 1;
  rotated.m_fFields[2][2] = 1;
  rotated.m_fFields[0][3] = 10;
  rotated.m_fFields[1][3] = 20;
  rotated.m_fFields[2][3] = 30;
  ASSERT_EQ(lib3mf_model_addbuilditem(model, tet, &rotated, &item), LIB3MF_OK);
  lib3mf_release(item);
  PLib3MFModelComponentsObject* group = nullptr;
  ASSERT_EQ(lib3mf_model_addcomponentsobject(model, &group), LIB3MF_OK);
  MODELTRANSFORM inner = identity(), outer = identity();
  inner.m_fFields[0][3] = 100;
  outer.m_fFields[2][3] = -5;
  PLib3MFModelComponent* component = nullptr;
  ASSERT_EQ(lib3mf_componentsobject_addcomponent(group, tet, &inner, &component), LIB3MF_OK);
  lib3mf_release(component);
  ASSERT_EQ(lib3mf_model_addbuilditem(model, group, &outer, &item), LIB3MF_OK);
  lib3mf_release(item);
  PLib3MFModelWriter* writer = nullptr;
  ASSERT_EQ(lib3mf_model_querywriter(model, "3mf", &writer), LIB3MF_OK);
  const fs::path path = test::scratch_dir("mm_3mf") / "three-items.3mf";
  ASSERT_EQ(lib3mf_writer_writetofileutf8(writer, path.c_str()), LIB3MF_OK);
  lib3mf_release(writer);
  lib3mf_release(group);
  lib3mf_release(tet);
  lib3mf_release(model);

  ReadReport report;
  const Mesh m = read_mesh(path.string(), &report);
  EXPECT_EQ(report.objects, 3);
  ASSERT_EQ(m.num_vertices(), 12);
  ASSERT_EQ(m.num_faces(), 12);
  EXPECT_EQ(m.points.row(1), Eigen::RowVector3d(1, 0, 0));
  EXPECT_EQ(m.points.row(5), Eigen::RowVector3d(10, 21, 30));  // (1, 0, 0) rotated and moved
  EXPECT_EQ(m.points.row(6), Eigen::RowVector3d(9, 20, 30));   // (0, 1, 0)
  EXPECT_EQ(m.points.row(11), Eigen::RowVector3d(100, 0, -4)); // (0, 0, 1) through both
  EXPECT_EQ(m.faces[4], (std::vector<int>{4, 6, 5}));         // the second item's indices follow the first's
}

TEST(ThreeMf, ObjectsAreChosenByNameAndCopiesKeepTheName) {
  Mesh a = test::quad_and_triangle(), b = a;
  b.points.col(0).array() += 10;
  const std::string bytes = three_mf_build_bytes({{"bracket", a}, {"lid", b}, {"bracket", a}}, "inch");
  ReadReport all;
  const Mesh whole = parse_mesh(bytes, "3mf", "build.3mf", &all);
  EXPECT_EQ(all.objects, 3);
  EXPECT_EQ(all.object_names, (std::vector<std::string>{"bracket", "lid", "bracket"}));
  EXPECT_EQ(whole.num_vertices(), 3 * a.num_vertices());
  ReadReport one;
  const Mesh lid = parse_mesh(bytes, "3mf", "build.3mf", &one, ReadOptions{"lid"});
  EXPECT_EQ(one.objects, 1);
  EXPECT_EQ(one.unit, "inch");
  ASSERT_EQ(lid.num_vertices(), b.num_vertices());
  EXPECT_EQ(lid.points(0, 0), static_cast<double>(static_cast<float>(b.points(0, 0))));
  ReadReport two;
  EXPECT_EQ(parse_mesh(bytes, "3mf", "build.3mf", &two, ReadOptions{"bracket"}).num_vertices(), 2 * a.num_vertices());
  EXPECT_EQ(two.objects, 2);
  try {
    parse_mesh(bytes, "3mf", "build.3mf", nullptr, ReadOptions{"hinge"});
    FAIL() << "an unknown object was read";
  } catch (const InputError& e) {
    EXPECT_EQ(e.source(), "build.3mf");
    EXPECT_NE(e.reason().find("no 3MF build item holds an object named \"hinge\" (objects: \"bracket\", \"lid\", \"bracket\")"),
              std::string::npos) << e.reason();
  }
  const std::string stl = mesh_file_bytes(a, "a.stl");
  EXPECT_THROW(parse_mesh(stl, "stl", "a.stl", nullptr, ReadOptions{"lid"}), InputError);
  // A copy of one object is written as that object, named.
  ReadReport copy;
  parse_mesh(mesh_file_bytes(lid, "copy.3mf", WriteOptions{"inch", 0, "lid"}), "3mf", "copy.3mf", &copy);
  EXPECT_EQ(copy.object_names, (std::vector<std::string>{"lid"}));
}

TEST(ThreeMf, DamagedOrEmptyPackagesAreRefusedByName) {
  const fs::path dir = test::scratch_dir("mm_3mf");
  const std::string good_path = (dir / "good.3mf").string();
  write_mesh(test::quad_and_triangle(), good_path);
  const std::string good = test::slurp(good_path);
  auto expect_refused = [&](const std::string& bytes, const std::string& name, const std::string& why) {
    test::expect_refused(dir, bytes, name, why);
  };
  expect_refused(good.substr(0, good.size() / 2), "truncated.3mf", "not a readable 3MF file");
  expect_refused("PK\x03\x04 not really a zip", "junk.3mf", "not a readable 3MF file");
  std::string flipped = good;
  flipped[flipped.size() / 3] ^= 0x55;
  expect_refused(flipped, "flipped.3mf", "3MF");
  expect_refused("", "empty.3mf", "empty");
  // A model with no build items makes nothing.
  NMR::PLib3MFModel* model = nullptr;
  ASSERT_EQ(NMR::lib3mf_createmodel(&model), LIB3MF_OK);
  NMR::PLib3MFModelWriter* writer = nullptr;
  ASSERT_EQ(NMR::lib3mf_model_querywriter(model, "3mf", &writer), LIB3MF_OK);
  const fs::path empty = dir / "no-items.3mf";
  ASSERT_EQ(NMR::lib3mf_writer_writetofileutf8(writer, empty.c_str()), LIB3MF_OK);
  NMR::lib3mf_release(writer);
  NMR::lib3mf_release(model);
  expect_refused(test::slurp(empty), "no-items.3mf", "no build items");
}

}  // namespace
}  // namespace mm
