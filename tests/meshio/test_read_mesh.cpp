// Every shared mesh reads with the counts of its README / header; STL welding agrees with
// OpenMesh's own STL reader (an independent implementation) and keeps every triangle.
#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "common/shared_meshes.h"
#include "meshio/read_mesh.h"
#include "meshio/repair_manifold.h"
#include "common/temp_dir.h"

namespace {

struct Expected {
  const char* file;
  int vertices;
  int faces;
};

// OFF: the README's vertex counts and each header's face count. STL: vertices after welding
// (cross-checked against OpenMesh below), faces = triangles in the file (84 + 50 n bytes).
const Expected kShared[] = {
    {"fandisk.off", 6475, 12946},       {"fandisk_quads.off", 766, 764},
    {"chamfer-cube.off", 24, 26},       {"sphere_low.off", 589, 1174},
    {"hemisphere.off", 1861, 3600},     {"bunny_adaptive.off", 5884, 11764},
    {"abc5.stl", 2560, 5080},           {"abc6.stl", 516, 1032},
    {"abc7.stl", 254, 504},             {"abc8.stl", 1529, 3058},
    {"abc9.stl", 632, 1260},            {"blade.stl", 6655, 13306},
    {"bracket-3.stl", 7267, 14538},     {"rocker.stl", 6533, 13066},
};

TEST(ReadMesh, SharedMeshesHaveTheirCounts) {
  MM_REQUIRE_SHARED_MESHES();
  for (const auto& e : kShared) {
    SCOPED_TRACE(e.file);
    std::string path = mm::test::shared_mesh(e.file);
    mm::ReadReport report;
    mm::Mesh m = mm::read_mesh(path, &report);
    EXPECT_EQ(m.num_vertices(), e.vertices);
    EXPECT_EQ(m.num_faces(), e.faces);
    EXPECT_EQ(report.degenerate_faces_dropped, 0);
    EXPECT_EQ(report.unreferenced_vertices, 0);
    if (std::string(e.file).find(".stl") != std::string::npos) {
      EXPECT_EQ(report.format, "stl-binary");
      auto bytes = std::filesystem::file_size(path);
      EXPECT_EQ(static_cast<std::uintmax_t>(84 + 50 * m.num_faces()), bytes);
      EXPECT_EQ(report.welded_vertices, 3 * m.num_faces() - m.num_vertices());
    }
  }
}

TEST(ReadMesh, StlWeldingAgreesWithOpenMesh) {
  MM_REQUIRE_SHARED_MESHES();
  for (const auto& e : kShared) {
    std::string file = e.file;
    if (file.find(".stl") == std::string::npos) continue;
    SCOPED_TRACE(file);
    OpenMesh::TriMesh_ArrayKernelT<> om;
    ASSERT_TRUE(OpenMesh::IO::read_mesh(om, mm::test::shared_mesh(file)));
    mm::Mesh m = mm::read_mesh(mm::test::shared_mesh(file));
    EXPECT_EQ(static_cast<size_t>(m.num_vertices()), om.n_vertices());
    // Same welding order (first appearance), so the positions agree vertex by vertex.
    for (auto v : om.vertices())
      for (int k = 0; k < 3; ++k) ASSERT_EQ(static_cast<float>(m.points(v.idx(), k)), om.point(v)[k]);
  }
}

TEST(ReadMesh, SharedMeshesAreManifoldAlready) {
  MM_REQUIRE_SHARED_MESHES();
  for (const auto& e : kShared) {
    SCOPED_TRACE(e.file);
    mm::ManifoldRepair r;
    mm::Mesh m = mm::read_mesh_manifold(mm::test::shared_mesh(e.file), nullptr, &r);
    EXPECT_EQ(r.vertices_duplicated, 0);
    EXPECT_EQ(m.num_vertices(), e.vertices);
  }
}

TEST(ReadMesh, OffKeepsFullDoublePrecisionAndOrder) {
  MM_REQUIRE_SHARED_MESHES();
  mm::Mesh m = mm::read_mesh(mm::test::shared_mesh("fandisk_quads.off"));
  // First vertex line of the file is "2.16697 16.6226 0"; float would give 2.1669700145721436.
  EXPECT_EQ(m.points(0, 0), 2.16697);
  EXPECT_EQ(m.points(0, 1), 16.6226);
  EXPECT_EQ(m.points(0, 2), 0.0);
}

std::string temp_path(const std::string& name) {
  return (mm::test::scratch_dir("mm_meshio_test") / name).string();
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

TEST(ReadMesh, AsciiStlIsWeldedInOrderOfFirstAppearance) {
  std::string p = temp_path("square.stl");
  write_text(p,
             "solid square\n"
             "  facet normal 0 0 1\n    outer loop\n      vertex 0 0 0\n      vertex 1 0 0\n"
             "      vertex 1 1 0\n    endloop\n  endfacet\n"
             "  facet normal 0 0 1\n    outer loop\n      vertex 0 0 0\n      vertex 1 1 0\n"
             "      vertex -0 1 0\n    endloop\n  endfacet\n"
             "endsolid square\n");
  mm::ReadReport r;
  mm::Mesh m = mm::read_mesh(p, &r);
  EXPECT_EQ(r.format, "stl-ascii");
  ASSERT_EQ(m.num_vertices(), 4);
  EXPECT_EQ(r.welded_vertices, 2);
  EXPECT_EQ(m.faces, (std::vector<std::vector<int>>{{0, 1, 2}, {0, 2, 3}}));
  EXPECT_EQ(m.points(3, 0), 0.0);
}

TEST(ReadMesh, ObjAcceptsSlashesAndNegativeIndices) {
  std::string p = temp_path("quad.obj");
  write_text(p, "# quad\nv 0 0 0\nv 1 0 0 1.0\nv 1 1 0 0.5 0.5 0.5\nv 0 1 0\nvt 0 0\nvn 0 0 1\n"
                "g part\nf 1/1/1 2//1 3/1 -1\n");
  mm::Mesh m = mm::read_mesh(p);
  ASSERT_EQ(m.num_faces(), 1);
  EXPECT_EQ(m.faces[0], (std::vector<int>{0, 1, 2, 3}));
}

TEST(ReadMesh, BinaryPlyBigEndianWithExtraProperties) {
  std::string p = temp_path("tri.ply");
  std::string s =
      "ply\nformat binary_big_endian 1.0\ncomment test\nelement vertex 3\nproperty uchar red\n"
      "property double x\nproperty double y\nproperty double z\nelement face 1\n"
      "property list uchar uint vertex_indices\nproperty float quality\nend_header\n";
  auto be = [&](const void* src, size_t n) {
    const auto* b = static_cast<const unsigned char*>(src);
    for (size_t k = 0; k < n; ++k) s += static_cast<char>(b[n - 1 - k]);
  };
  const double xyz[3][3] = {{0.1, 0.2, 0.3}, {1.0 / 3.0, 0, 0}, {0, 1e-300, 7}};
  for (auto& v : xyz) {
    s += '\x07';
    for (double d : v) be(&d, 8);
  }
  s += '\x03';
  for (uint32_t i : {2u, 0u, 1u}) be(&i, 4);
  float q = 1.5f;
  be(&q, 4);
  write_text(p, s);
  mm::ReadReport r;
  mm::Mesh m = mm::read_mesh(p, &r);
  EXPECT_EQ(r.format, "ply-binary");
  ASSERT_EQ(m.num_vertices(), 3);
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) EXPECT_EQ(m.points(i, k), xyz[i][k]);
  EXPECT_EQ(m.faces, (std::vector<std::vector<int>>{{2, 0, 1}}));
}

TEST(ReadMesh, DegenerateFacesAreCountedNotSilent) {
  std::string p = temp_path("degenerate.off");
  // Face 1 repeats a vertex in a row (collapsed to a triangle); face 2 has 2 distinct vertices.
  write_text(p, "OFF\n4 3 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n4 0 2 2 3\n3 1 1 3\n");
  mm::ReadReport r;
  mm::Mesh m = mm::read_mesh(p, &r);
  EXPECT_EQ(m.faces, (std::vector<std::vector<int>>{{0, 1, 2}, {0, 2, 3}}));
  EXPECT_EQ(r.collapsed_faces, 1);
  EXPECT_EQ(r.degenerate_faces_dropped, 1);
}

TEST(ReadMesh, MissingFileAndDirectoryNameThePath) {
  try {
    mm::read_mesh("/nonexistent/part.stl");
    FAIL() << "no exception";
  } catch (const mm::InputError& e) {
    EXPECT_EQ(e.source(), "/nonexistent/part.stl");
    EXPECT_EQ(e.reason(), "no such file");
  }
  std::string dir = temp_path("folder.off");
  std::filesystem::create_directories(dir);
  try {
    mm::read_mesh(dir);
    FAIL() << "no exception";
  } catch (const mm::InputError& e) {
    EXPECT_NE(e.reason().find("is a directory"), std::string::npos);
  }
}

TEST(ReadMesh, ParseMeshFromMemoryNamesTheSource) {
  mm::Mesh m = mm::parse_mesh("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "off", "upload#1");
  EXPECT_EQ(m.num_faces(), 1);
  try {
    mm::parse_mesh("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n", "off", "upload#2");
    FAIL() << "no exception";
  } catch (const mm::InputError& e) {
    EXPECT_EQ(e.source(), "upload#2");
    EXPECT_NE(e.reason().find("truncated"), std::string::npos);
  }
}

}  // namespace

namespace {

// Geomview binary OFF: big-endian 32-bit words after the text header line.
struct BinaryOff {
  std::string bytes;
  void word(std::uint32_t w) {
    for (int shift = 24; shift >= 0; shift -= 8) bytes.push_back(static_cast<char>((w >> shift) & 0xff));
  }
  void integer(std::int32_t i) { word(static_cast<std::uint32_t>(i)); }
  void real(float f) {
    std::uint32_t w;
    std::memcpy(&w, &f, sizeof w);
    word(w);
  }
};

// A tetrahedron as COFF BINARY: RGBA per vertex, one face with a colour, one without.
std::string binary_tetrahedron() {
  BinaryOff off;
  off.bytes = "# written by a test\nCOFF BINARY\n";
  off.integer(4), off.integer(4), off.integer(6);
  const float p[4][3] = {{0, 0, 0}, {1.5f, 0, 0}, {0, 2.25f, 0}, {0, 0, -3}};
  for (const auto& v : p) {
    for (float x : v) off.real(x);
    for (int c = 0; c < 4; ++c) off.real(0.5f);
  }
  const int f[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  for (int i = 0; i < 4; ++i) {
    off.integer(3);
    for (int v : f[i]) off.integer(v);
    off.integer(i % 2 == 0 ? 3 : 0);
    if (i % 2 == 0)
      for (int c = 0; c < 3; ++c) off.real(1);
  }
  return off.bytes;
}

}  // namespace

TEST(ReadMesh, BinaryOffWithColoursReadsExactly) {
  mm::ReadReport report;
  const mm::Mesh m = mm::parse_mesh(binary_tetrahedron(), "off", "tet.off", &report);
  EXPECT_EQ(report.format, "off-binary");
  ASSERT_EQ(m.num_vertices(), 4);
  EXPECT_EQ(m.points(1, 0), 1.5);
  EXPECT_EQ(m.points(2, 1), 2.25);
  EXPECT_EQ(m.points(3, 2), -3);
  ASSERT_EQ(m.num_faces(), 4);
  EXPECT_EQ(m.faces[0], (std::vector<int>{0, 2, 1}));
  EXPECT_EQ(m.faces[3], (std::vector<int>{1, 2, 3}));
}

TEST(ReadMesh, BrokenBinaryOffIsRefusedWithTheReason) {
  const std::string good = binary_tetrahedron();
  const auto reason = [](const std::string& bytes) {
    try {
      mm::parse_mesh(bytes, "off", "tet.off");
    } catch (const mm::InputError& e) {
      EXPECT_EQ(e.source(), "tet.off");
      return e.reason();
    }
    return std::string("accepted");
  };
  // Every cut inside the data is refused, never read past.
  for (std::size_t n = good.find("BINARY\n") + 7; n < good.size(); n += 5) EXPECT_NE(reason(good.substr(0, n)), "accepted") << n;
  EXPECT_NE(reason(good.substr(0, good.size() - 2)).find("truncated"), std::string::npos);
  std::string bad = good;
  bad[bad.size() - 5] = 9;  // the last face's last index (before its colour count): 9 of 4 vertices
  EXPECT_NE(reason(bad).find("out of range"), std::string::npos);
  std::string absurd = good;
  absurd[good.find("BINARY\n") + 7] = 0x7f;  // the vertex count's top byte
  EXPECT_NE(reason(absurd).find("absurd counts"), std::string::npos);
  EXPECT_NE(reason(good + "xx").find("after the 4 faces"), std::string::npos);
  EXPECT_NE(reason("OFF BINARY extra\n").find("after \"BINARY\""), std::string::npos);
}

TEST(ReadMesh, PlyTakesEveryPropertyTypeByBothNames) {
  // Each scalar type under both of its names: as a coordinate, as an ignored property, as a list's
  // count and entries; a second list (texture coordinates) on the face is skipped.
  const char* names[8][2] = {{"char", "int8"},   {"uchar", "uint8"}, {"short", "int16"},   {"ushort", "uint16"},
                             {"int", "int32"},   {"uint", "uint32"}, {"float", "float32"}, {"double", "float64"}};
  for (int name = 0; name < 2; ++name)
    for (int t = 0; t < 8; ++t) {
      SCOPED_TRACE(names[t][name]);
      const char* ty = names[t][name];
      const char* count = t < 6 ? ty : "uchar";  // list counts must be integers
      const char* index = t < 6 ? ty : "int";
      std::string s = std::string("ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty ") + ty + " x\n" +
                      "property " + ty + " extra\nproperty float y\nproperty " + ty + " z\nelement face 1\n" +
                      "property list " + count + " " + index + " vertex_indices\nproperty list uchar " + ty +
                      " texcoord\nproperty " + ty + " quality\nend_header\n";
      auto put = [&s](double v, int type) {
        unsigned char b[8];
        switch (type) {
          case 0: { const auto x = static_cast<std::int8_t>(v); std::memcpy(b, &x, 1); break; }
          case 1: { const auto x = static_cast<std::uint8_t>(v); std::memcpy(b, &x, 1); break; }
          case 2: { const auto x = static_cast<std::int16_t>(v); std::memcpy(b, &x, 2); break; }
          case 3: { const auto x = static_cast<std::uint16_t>(v); std::memcpy(b, &x, 2); break; }
          case 4: { const auto x = static_cast<std::int32_t>(v); std::memcpy(b, &x, 4); break; }
          case 5: { const auto x = static_cast<std::uint32_t>(v); std::memcpy(b, &x, 4); break; }
          case 6: { const auto x = static_cast<float>(v); std::memcpy(b, &x, 4); break; }
          default: std::memcpy(b, &v, 8);
        }
        const int n = type == 0 || type == 1 ? 1 : type == 2 || type == 3 ? 2 : type == 7 ? 8 : 4;
        s.append(reinterpret_cast<const char*>(b), static_cast<std::size_t>(n));
      };
      const double p[3][3] = {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}};
      for (const auto& v : p) {
        put(v[0], t), put(99, t), put(v[1], 6), put(v[2], t);
      }
      const int ct = t < 6 ? t : 1, it = t < 6 ? t : 4;
      put(3, ct), put(2, it), put(0, it), put(1, it);
      put(2, 1), put(5, t), put(6, t);
      put(1, t);
      mm::ReadReport r;
      const mm::Mesh m = mm::parse_mesh(s, "ply", "types.ply", &r);
      EXPECT_EQ(r.format, "ply-binary");
      ASSERT_EQ(m.num_vertices(), 3);
      for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) EXPECT_EQ(m.points(i, k), p[i][k]);
      EXPECT_EQ(m.faces, (std::vector<std::vector<int>>{{2, 0, 1}}));
    }
}
