// glTF 2.0 and GLB through tinygltf: what write_mesh writes reads back; node transforms apply
// through the hierarchy; Draco-compressed primitives (written here by libdraco's encoder)
// decode; external files are never opened and damaged files are refused by name.
#include <tiny_gltf.h>
#include <gtest/gtest.h>

#include <draco/compression/encode.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "common/temp_dir.h"
#include "format_fixtures.h"
#include "meshio/read_mesh.h"

namespace mm {
namespace {

namespace fs = std::filesystem;

TEST(Gltf, WrittenMeshReadsBackInBothForms) {
  const fs::path dir = test::scratch_dir("mm_gltf");
  const Mesh m = test::quad_and_triangle();
  for (const char* ext : {".glb", ".gltf"}) {
    const std::string path = (dir / (std::string("part") + ext)).string();
    write_mesh(m, path);
    ReadReport report;
    const Mesh back = read_mesh(path, &report);
    EXPECT_EQ(report.format, std::string(ext + 1));
    EXPECT_EQ(report.unit, "meter");
    ASSERT_EQ(back.num_vertices(), m.num_vertices()) << ext;
    for (int i = 0; i < m.num_vertices(); ++i)
      for (int k = 0; k < 3; ++k) EXPECT_EQ(back.points(i, k), static_cast<double>(static_cast<float>(m.points(i, k))));
    const std::vector<std::vector<int>> faces{{0, 1, 2}, {0, 2, 3}, {3, 2, 4}};
    EXPECT_EQ(back.faces, faces) << ext;
  }
}

// A scene of a parent node (translated) holding a child node (rotated 90 degrees about z, scaled
// by 2) with the mesh, and a second root placing the same mesh by a column-major matrix.
TEST(Gltf, NodeTransformsApplyThroughTheHierarchy) {
  const fs::path dir = test::scratch_dir("mm_gltf");
  const std::string plain = (dir / "one.gltf").string();
  Mesh tri;
  tri.points.resize(3, 3);
  tri.points << 1, 0, 0, 0, 1, 0, 0, 0, 1;
  tri.faces = {{0, 1, 2}};
  write_mesh(tri, plain);
  tinygltf::TinyGLTF io;
  tinygltf::Model model;
  std::string err, warn;
  ASSERT_TRUE(io.LoadASCIIFromFile(&model, &err, &warn, plain)) << err;
  tinygltf::Node parent, child, other;
  parent.translation = {10, 20, 30};
  parent.children = {2};
  child.mesh = 0;
  child.rotation = {0, 0, std::sqrt(0.5), std::sqrt(0.5)};  // x, y, z, w
  child.scale = {2, 2, 2};
  other.mesh = 0;
  other.matrix = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -1, -2, -3, 1};  // translation (-1, -2, -3)
  model.nodes = {model.nodes[0], parent, child, other};
  model.scenes[0].nodes = {1, 3};
  const std::string path = (dir / "tree.glb").string();
  ASSERT_TRUE(io.WriteGltfSceneToFile(&model, path, true, true, false, true));
  ReadReport report;
  const Mesh m = read_mesh(path, &report);
  EXPECT_EQ(report.objects, 2);
  ASSERT_EQ(m.num_vertices(), 6);
  // (1, 0, 0) scaled to (2, 0, 0), rotated to (0, 2, 0), moved to (10, 22, 30).
  EXPECT_NEAR((m.points.row(0) - Eigen::RowVector3d(10, 22, 30)).norm(), 0, 1e-6);
  EXPECT_NEAR((m.points.row(1) - Eigen::RowVector3d(8, 20, 30)).norm(), 0, 1e-6);
  EXPECT_EQ(m.points.row(5), Eigen::RowVector3d(-1, -2, -2));
  EXPECT_EQ(m.faces[1], (std::vector<int>{3, 4, 5}));
}

TEST(Gltf, DracoCompressedPrimitivesDecode) {
  // The tetrahedron compressed by libdraco, in a GLB whose primitive names it through
  // KHR_draco_mesh_compression.
  draco::TriangleSoupMeshBuilder builder;
  builder.Start(4);
  const int pos = builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  const float v[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  const int t[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  for (int f = 0; f < 4; ++f)
    builder.SetAttributeValuesForFace(pos, draco::FaceIndex(f), v[t[f][0]], v[t[f][1]], v[t[f][2]]);
  std::unique_ptr<draco::Mesh> dm = builder.Finalize();
  ASSERT_TRUE(dm);
  draco::Encoder encoder;
  encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, 16);
  draco::EncoderBuffer encoded;
  ASSERT_TRUE(encoder.EncodeMeshToBuffer(*dm, &encoded).ok());
  const int draco_id = static_cast<int>(dm->GetNamedAttribute(draco::GeometryAttribute::POSITION)->unique_id());

  tinygltf::Model model;
  model.asset.version = "2.0";
  tinygltf::Buffer buffer;
  buffer.data.assign(encoded.data(), encoded.data() + encoded.size());
  model.buffers.push_back(buffer);
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteLength = encoded.size();
  model.bufferViews.push_back(view);
  tinygltf::Accessor acc;  // what a viewer without Draco would see: no buffer view
  acc.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
  acc.type = TINYGLTF_TYPE_VEC3;
  acc.count = 4;
  acc.minValues = {0, 0, 0};
  acc.maxValues = {1, 1, 1};
  model.accessors.push_back(acc);
  tinygltf::Primitive prim;
  prim.attributes["POSITION"] = 0;
  prim.mode = TINYGLTF_MODE_TRIANGLES;
  tinygltf::Value::Object attributes{{"POSITION", tinygltf::Value(draco_id)}};
  tinygltf::Value::Object ext{{"bufferView", tinygltf::Value(0)}, {"attributes", tinygltf::Value(attributes)}};
  prim.extensions["KHR_draco_mesh_compression"] = tinygltf::Value(ext);
  tinygltf::Mesh mesh;
  mesh.primitives.push_back(prim);
  model.meshes.push_back(mesh);
  tinygltf::Node node;
  node.mesh = 0;
  model.nodes.push_back(node);
  tinygltf::Scene scene;
  scene.nodes = {0};
  model.scenes.push_back(scene);
  model.extensionsUsed = model.extensionsRequired = {"KHR_draco_mesh_compression"};
  const fs::path path = test::scratch_dir("mm_gltf") / "draco.glb";
  tinygltf::TinyGLTF io;
  ASSERT_TRUE(io.WriteGltfSceneToFile(&model, path.string(), true, true, false, true));

  const Mesh m = read_mesh(path.string());
  ASSERT_EQ(m.num_faces(), 4);
  ASSERT_GE(m.num_vertices(), 4);
  // Every corner of every face is one of the tetrahedron's corners (16-bit quantisation of a unit cube).
  for (const auto& f : m.faces) {
    ASSERT_EQ(f.size(), 3u);
    for (int c : f) {
      double best = 1e9;
      for (const auto& p : v) best = std::min(best, (m.points.row(c) - Eigen::RowVector3d(p[0], p[1], p[2])).norm());
      EXPECT_LT(best, 1e-4);
    }
  }
}

TEST(Gltf, ExternalFilesAreNeverOpenedAndDamageIsRefusedByName) {
  const fs::path dir = test::scratch_dir("mm_gltf");
  std::ofstream(dir / "secret.bin") << std::string(48, 'x');
  const std::string external =
      R"({"asset":{"version":"2.0"},"buffers":[{"uri":"secret.bin","byteLength":48}],)"
      R"("bufferViews":[{"buffer":0,"byteLength":36}],"accessors":[{"bufferView":0,"componentType":5126,)"
      R"("count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,1]}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],)"
      R"("nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]})";
  auto expect_refused = [&](const std::string& bytes, const std::string& name, const std::string& why) {
    test::expect_refused(dir, bytes, name, why);
  };
  expect_refused(external, "external.gltf", "external file");
  const std::string glb_path = (dir / "good.glb").string();
  write_mesh(test::quad_and_triangle(), glb_path);
  const std::string good = test::slurp(glb_path);
  expect_refused(good.substr(0, good.size() - 7), "truncated.glb", "not a readable GLB file");
  expect_refused("{\"asset\":", "cut.gltf", "not a readable glTF file");
  // An accessor reaching past its buffer, and an index past the vertices.
  std::string past = R"({"asset":{"version":"2.0"},"buffers":[{"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAA","byteLength":12}],)"
                     R"("bufferViews":[{"buffer":0,"byteLength":12}],"accessors":[{"bufferView":0,"componentType":5126,)"
                     R"("count":3,"type":"VEC3","min":[0,0,0],"max":[0,0,0]}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],)"
                     R"("nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]})";
  expect_refused(past, "past.gltf", "glTF");
  expect_refused(R"({"asset":{"version":"2.0"},"nodes":[{}],"scenes":[{"nodes":[0]}]})", "empty.gltf",
                 "no triangle primitive");
}

TEST(Gltf, DracoCompressedCopiesKeepTheVertexOrderWithinTheirQuantisation) {
  Mesh m;
  m.points.resize(5, 3);
  m.points << 0, 0, 0, 2, 0, 0, 2, 1, 0, 0, 1, 0, 1, 0.5, 1.25;
  m.faces = {{0, 3, 2, 1}, {0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}};
  for (const char* ext : {"glb", "gltf"}) {
    const fs::path path = test::scratch_dir("mm_gltf") / (std::string("draco.") + ext);
    WriteOptions options;
    options.draco_bits = 16;
    write_mesh(m, path.string(), options);
    ReadReport report;
    const Mesh back = read_mesh(path.string(), &report);
    EXPECT_TRUE(report.draco) << ext;
    ASSERT_EQ(back.num_vertices(), 5) << ext;
    // 16 bits over the largest side (2): a step of 3.1e-5, half of it at most per coordinate.
    EXPECT_LT((back.points - m.points).cwiseAbs().maxCoeff(), 2.0 / 65535) << ext;
    EXPECT_EQ(back.faces, (std::vector<std::vector<int>>{{0, 3, 2}, {0, 2, 1}, {0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}}))
        << ext;
    // The plain writer's file is larger and not compressed.
    const fs::path plain = test::scratch_dir("mm_gltf") / (std::string("plain.") + ext);
    write_mesh(m, plain.string());
    ReadReport plain_report;
    read_mesh(plain.string(), &plain_report);
    EXPECT_FALSE(plain_report.draco);
  }
  WriteOptions bad;
  bad.draco_bits = 40;
  EXPECT_THROW(write_mesh(m, (test::scratch_dir("mm_gltf") / "bad.glb").string(), bad), InputError);
}

}  // namespace
}  // namespace mm
