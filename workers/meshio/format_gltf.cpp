// glTF 2.0 (.gltf, JSON with embedded data: URIs) and GLB through tinygltf, with
// KHR_draco_mesh_compression primitives decoded by libdraco (both Debian packages). Reading takes
// the default scene (else the first; else every root node): each node's mesh primitives of
// triangles (also strips and fans), their POSITION accessor and indices, with the node's world
// transform (matrix, or translation x rotation x scale, through its parents) applied, in node
// order. Images are never decoded and external files are never opened: a .gltf that refers to a
// file outside itself is refused (meshmark reads only the bytes it was handed).
#include <tiny_gltf.h>

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>

#include <Eigen/Geometry>
#include <cstring>
#include <functional>
#include <limits>
#include <sstream>

#include "meshio/formats.h"

namespace mm::formats {
namespace {

constexpr int kMaxNodeDepth = 64;
constexpr long long kMaxCount = 100'000'000;

bool no_images(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) {
  return true;
}
// "Exists", so that tinygltf asks to read it and the refusal names the reason.
bool no_file_exists(const std::string&, void*) { return true; }
std::string same_path(const std::string& p, void*) { return p; }
bool no_file_read(std::vector<unsigned char>*, std::string* err, const std::string& p, void*) {
  if (err) *err += "refers to the external file \"" + p + "\" (only self-contained glTF and GLB are read)";
  return false;
}
bool no_file_write(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err) *err += "writing files is not allowed";
  return false;
}

Eigen::Matrix4d node_matrix(const tinygltf::Node& n) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  if (n.matrix.size() == 16) {
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) m(r, c) = n.matrix[static_cast<std::size_t>(4 * c + r)];  // column-major
    return m;
  }
  Eigen::Affine3d a = Eigen::Affine3d::Identity();
  if (n.translation.size() == 3) a.translate(Eigen::Vector3d(n.translation[0], n.translation[1], n.translation[2]));
  if (n.rotation.size() == 4)
    a.rotate(Eigen::Quaterniond(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]).normalized());
  if (n.scale.size() == 3) a.scale(Eigen::Vector3d(n.scale[0], n.scale[1], n.scale[2]));
  return a.matrix();
}

struct Collector {
  const tinygltf::Model& model;
  const std::string& source;
  std::vector<Eigen::Vector3d> points;
  std::vector<std::vector<int>> faces;
  int primitives = 0, skipped = 0, draco_primitives = 0;

  [[noreturn]] void fail(const std::string& why) const { throw InputError(source, why); }

  // The bytes of an accessor's element i, checked against its buffer.
  const unsigned char* element(const tinygltf::Accessor& acc, std::size_t i, std::size_t size, const char* what) const {
    if (acc.bufferView < 0 || acc.bufferView >= static_cast<int>(model.bufferViews.size()))
      fail(std::string("glTF ") + what + " accessor has no valid buffer view");
    const tinygltf::BufferView& view = model.bufferViews[static_cast<std::size_t>(acc.bufferView)];
    if (view.buffer < 0 || view.buffer >= static_cast<int>(model.buffers.size()))
      fail(std::string("glTF ") + what + " buffer view has no valid buffer");
    const std::vector<unsigned char>& data = model.buffers[static_cast<std::size_t>(view.buffer)].data;
    const std::size_t stride = view.byteStride ? view.byteStride : size;
    const std::size_t at = view.byteOffset + acc.byteOffset + i * stride;
    if (view.byteOffset + view.byteLength > data.size() || at + size > view.byteOffset + view.byteLength)
      fail(std::string("glTF ") + what + " accessor reaches past its buffer");
    return data.data() + at;
  }

  void add_primitive(const tinygltf::Primitive& p, const Eigen::Matrix4d& world) {
    if (p.mode != TINYGLTF_MODE_TRIANGLES && p.mode != TINYGLTF_MODE_TRIANGLE_STRIP && p.mode != TINYGLTF_MODE_TRIANGLE_FAN) {
      ++skipped;  // points and lines carry no surface
      return;
    }
    std::vector<Eigen::Vector3d> local;
    std::vector<long long> index;
    const auto draco = p.extensions.find("KHR_draco_mesh_compression");
    if (draco != p.extensions.end()) {
      decode_draco(draco->second, local, index);
      ++draco_primitives;
    } else {
      const auto pos = p.attributes.find("POSITION");
      if (pos == p.attributes.end() || pos->second < 0 || pos->second >= static_cast<int>(model.accessors.size()))
        fail("glTF primitive has no POSITION accessor");
      const tinygltf::Accessor& acc = model.accessors[static_cast<std::size_t>(pos->second)];
      if (acc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT || acc.type != TINYGLTF_TYPE_VEC3 || acc.normalized)
        fail("glTF POSITION accessor is not float VEC3");
      if (static_cast<long long>(acc.count) > kMaxCount) fail("glTF POSITION accessor is too large");
      local.resize(acc.count);
      for (std::size_t i = 0; i < acc.count; ++i) {
        float xyz[3];
        std::memcpy(xyz, element(acc, i, 12, "POSITION"), 12);
        local[i] = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
      }
      if (p.indices >= 0) {
        if (p.indices >= static_cast<int>(model.accessors.size())) fail("glTF primitive's indices accessor does not exist");
        const tinygltf::Accessor& ia = model.accessors[static_cast<std::size_t>(p.indices)];
        const int size = ia.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE    ? 1
                         : ia.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 2
                         : ia.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT   ? 4
                                                                                      : 0;
        if (size == 0 || ia.type != TINYGLTF_TYPE_SCALAR) fail("glTF indices accessor is not unsigned scalars");
        if (static_cast<long long>(ia.count) > kMaxCount) fail("glTF indices accessor is too large");
        index.resize(ia.count);
        for (std::size_t i = 0; i < ia.count; ++i) {
          std::uint32_t v = 0;
          std::memcpy(&v, element(ia, i, static_cast<std::size_t>(size), "indices"), static_cast<std::size_t>(size));
          index[i] = v;
        }
      } else {
        index.resize(local.size());
        for (std::size_t i = 0; i < local.size(); ++i) index[i] = static_cast<long long>(i);
      }
    }
    if (static_cast<long long>(points.size() + local.size()) > kMaxCount) fail("glTF scene has too many vertices");
    const long long base = static_cast<long long>(points.size());
    for (const Eigen::Vector3d& q : local) {
      const Eigen::Vector3d w = (world * q.homogeneous()).head<3>();
      check_finite(w.data(), source, "glTF vertex " + std::to_string(points.size()));
      points.push_back(w);
    }
    for (long long v : index)
      if (v < 0 || v >= static_cast<long long>(local.size()))
        fail("glTF index " + std::to_string(v) + " out of range (" + std::to_string(local.size()) + " vertices)");
    auto tri = [&](long long a, long long b, long long c) {
      faces.push_back({static_cast<int>(base + index[a]), static_cast<int>(base + index[b]), static_cast<int>(base + index[c])});
    };
    const long long n = static_cast<long long>(index.size());
    if (p.mode == TINYGLTF_MODE_TRIANGLES) {
      for (long long i = 0; i + 2 < n; i += 3) tri(i, i + 1, i + 2);
    } else if (p.mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      for (long long i = 0; i + 2 < n; ++i) i % 2 ? tri(i + 1, i, i + 2) : tri(i, i + 1, i + 2);
    } else {
      for (long long i = 1; i + 1 < n; ++i) tri(0, i, i + 1);
    }
    ++primitives;
  }

  void decode_draco(const tinygltf::Value& ext, std::vector<Eigen::Vector3d>& local, std::vector<long long>& index) const {
    const tinygltf::Value& bv = ext.Get("bufferView");
    const tinygltf::Value& attributes = ext.Get("attributes");
    if (!bv.IsInt() || !attributes.IsObject() || !attributes.Get("POSITION").IsInt())
      fail("glTF KHR_draco_mesh_compression lacks its bufferView or POSITION attribute");
    const int view_id = bv.Get<int>();
    if (view_id < 0 || view_id >= static_cast<int>(model.bufferViews.size())) fail("glTF Draco buffer view does not exist");
    const tinygltf::BufferView& view = model.bufferViews[static_cast<std::size_t>(view_id)];
    if (view.buffer < 0 || view.buffer >= static_cast<int>(model.buffers.size())) fail("glTF Draco buffer does not exist");
    const std::vector<unsigned char>& data = model.buffers[static_cast<std::size_t>(view.buffer)].data;
    if (view.byteOffset + view.byteLength > data.size()) fail("glTF Draco buffer view reaches past its buffer");
    draco::DecoderBuffer buffer;
    buffer.Init(reinterpret_cast<const char*>(data.data() + view.byteOffset), view.byteLength);
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
    if (!decoded.ok()) fail("glTF Draco mesh does not decode: " + decoded.status().error_msg_string());
    const std::unique_ptr<draco::Mesh>& mesh = decoded.value();
    const draco::PointAttribute* pos =
        mesh->GetAttributeByUniqueId(static_cast<std::uint32_t>(attributes.Get("POSITION").Get<int>()));
    if (!pos || pos->num_components() != 3) fail("glTF Draco mesh has no 3-component POSITION attribute");
    if (static_cast<long long>(mesh->num_points()) > kMaxCount || static_cast<long long>(mesh->num_faces()) > kMaxCount)
      fail("glTF Draco mesh is too large");
    local.resize(mesh->num_points());
    for (draco::PointIndex i(0); i < mesh->num_points(); ++i) {
      float xyz[3];
      if (!pos->ConvertValue<float, 3>(pos->mapped_index(i), xyz)) fail("glTF Draco POSITION values do not convert");
      local[i.value()] = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
    }
    index.reserve(3 * static_cast<std::size_t>(mesh->num_faces()));
    for (draco::FaceIndex f(0); f < mesh->num_faces(); ++f)
      for (int k = 0; k < 3; ++k) index.push_back(mesh->face(f)[k].value());
  }

  void add_node(int id, const Eigen::Matrix4d& parent, int depth) {
    if (id < 0 || id >= static_cast<int>(model.nodes.size())) fail("glTF node " + std::to_string(id) + " does not exist");
    if (depth > kMaxNodeDepth) fail("glTF nodes nested deeper than " + std::to_string(kMaxNodeDepth) + " (or in a cycle)");
    const tinygltf::Node& n = model.nodes[static_cast<std::size_t>(id)];
    const Eigen::Matrix4d world = parent * node_matrix(n);
    if (n.mesh >= 0) {
      if (n.mesh >= static_cast<int>(model.meshes.size())) fail("glTF node " + std::to_string(id) + " names a missing mesh");
      for (const tinygltf::Primitive& p : model.meshes[static_cast<std::size_t>(n.mesh)].primitives) add_primitive(p, world);
    }
    for (int c : n.children) add_node(c, world, depth + 1);
  }
};

}  // namespace

Mesh parse_gltf(std::string_view bytes, const std::string& source, ReadReport& report, bool binary) {
  report.format = binary ? "glb" : "gltf";
  report.unit = "meter";  // glTF's unit
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(no_images, nullptr);
  loader.SetFsCallbacks({no_file_exists, same_path, no_file_read, no_file_write, nullptr});
  tinygltf::Model model;
  std::string err, warn;
  if (bytes.size() > std::numeric_limits<unsigned int>::max()) throw InputError(source, "too large for glTF");
  const bool ok = binary ? loader.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<const unsigned char*>(bytes.data()),
                                                       static_cast<unsigned int>(bytes.size()), "")
                         : loader.LoadASCIIFromString(&model, &err, &warn, bytes.data(),
                                                      static_cast<unsigned int>(bytes.size()), "");
  if (!ok) {
    while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
    throw InputError(source, std::string("not a readable ") + (binary ? "GLB" : "glTF") + " file: " +
                                 (err.empty() ? "tinygltf refused it" : err));
  }
  Collector c{model, source, {}, {}};
  std::vector<int> roots;
  if (!model.scenes.empty()) {
    const int s = model.defaultScene >= 0 && model.defaultScene < static_cast<int>(model.scenes.size()) ? model.defaultScene : 0;
    roots = model.scenes[static_cast<std::size_t>(s)].nodes;
  } else {
    std::vector<char> child(model.nodes.size(), 0);
    for (const auto& n : model.nodes)
      for (int k : n.children)
        if (k >= 0 && k < static_cast<int>(child.size())) child[static_cast<std::size_t>(k)] = 1;
    for (std::size_t i = 0; i < model.nodes.size(); ++i)
      if (!child[i]) roots.push_back(static_cast<int>(i));
  }
  for (int r : roots) c.add_node(r, Eigen::Matrix4d::Identity(), 0);
  if (c.primitives == 0) throw InputError(source, "glTF scene has no triangle primitive");
  report.objects = c.primitives;
  report.draco = c.draco_primitives > 0;
  Mesh m;
  m.points.resize(static_cast<Eigen::Index>(c.points.size()), 3);
  for (std::size_t i = 0; i < c.points.size(); ++i) m.points.row(static_cast<Eigen::Index>(i)) = c.points[i].transpose();
  m.faces = std::move(c.faces);
  return m;
}

namespace {

// The fanned triangles as one Draco mesh, vertices in their order (sequential coding keeps it),
// positions quantised to `bits`.
std::vector<unsigned char> draco_bytes(const Mesh& m, int bits, const std::string& path) {
  draco::Mesh dm;
  dm.set_num_points(static_cast<draco::PointIndex::ValueType>(m.num_vertices()));
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false, sizeof(float) * 3, 0);
  const int id = dm.AddAttribute(position, true, static_cast<draco::AttributeValueIndex::ValueType>(m.num_vertices()));
  for (int i = 0; i < m.num_vertices(); ++i) {
    const Eigen::Vector3f f = m.points.row(i).transpose().cast<float>();
    dm.attribute(id)->SetAttributeValue(draco::AttributeValueIndex(i), f.data());
  }
  for (const auto& f : m.faces)
    for (std::size_t k = 1; k + 1 < f.size(); ++k)
      dm.AddFace({draco::PointIndex(static_cast<std::uint32_t>(f[0])), draco::PointIndex(static_cast<std::uint32_t>(f[k])),
                  draco::PointIndex(static_cast<std::uint32_t>(f[k + 1]))});
  draco::Encoder encoder;
  encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, bits);
  encoder.SetEncodingMethod(draco::MESH_SEQUENTIAL_ENCODING);
  draco::EncoderBuffer out;
  const draco::Status status = encoder.EncodeMeshToBuffer(dm, &out);
  if (!status.ok()) throw InputError(path, "libdraco could not compress the mesh: " + status.error_msg_string());
  return {out.data(), out.data() + out.size()};
}

}  // namespace

std::string gltf_bytes(const Mesh& m, const std::string& path, bool binary, int draco_bits) {
  if (draco_bits != 0 && (draco_bits < 8 || draco_bits > 30))
    throw InputError(path, "Draco position quantisation of " + std::to_string(draco_bits) + " bits is outside 8..30");
  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "meshmark";
  std::vector<unsigned char> data;
  auto put = [&data](const void* p, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    data.insert(data.end(), b, b + n);
  };
  // A Draco copy's buffer is the Draco mesh alone: the plain arrays are only counted for it.
  const bool plain = draco_bits == 0;
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max()), hi = -lo;
  for (int i = 0; i < m.num_vertices(); ++i) {
    const Eigen::Vector3f f = m.points.row(i).transpose().cast<float>();
    lo = lo.cwiseMin(f);
    hi = hi.cwiseMax(f);
    if (plain) put(f.data(), 12);
  }
  const std::size_t position_bytes = 12 * static_cast<std::size_t>(m.num_vertices());
  std::size_t triangles = 0;
  for (const auto& f : m.faces)
    for (std::size_t k = 1; k + 1 < f.size(); ++k) {  // fan triangulation keeps the orientation
      const std::uint32_t t[3] = {static_cast<std::uint32_t>(f[0]), static_cast<std::uint32_t>(f[k]),
                                  static_cast<std::uint32_t>(f[k + 1])};
      if (plain) put(t, 12);
      ++triangles;
    }
  tinygltf::Buffer buffer;
  buffer.data = draco_bits ? draco_bytes(m, draco_bits, path) : std::move(data);
  const std::size_t draco_size = buffer.data.size();
  model.buffers.push_back(std::move(buffer));
  tinygltf::BufferView positions, indices;
  positions.buffer = indices.buffer = 0;
  positions.byteLength = position_bytes;
  positions.target = TINYGLTF_TARGET_ARRAY_BUFFER;
  indices.byteOffset = position_bytes;
  indices.byteLength = 12 * triangles;
  indices.target = TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER;
  model.bufferViews = {positions, indices};
  tinygltf::Accessor pa, ia;
  pa.bufferView = 0;
  pa.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
  pa.type = TINYGLTF_TYPE_VEC3;
  pa.count = static_cast<std::size_t>(m.num_vertices());
  pa.minValues = {lo.x(), lo.y(), lo.z()};
  pa.maxValues = {hi.x(), hi.y(), hi.z()};
  ia.bufferView = 1;
  ia.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
  ia.type = TINYGLTF_TYPE_SCALAR;
  ia.count = 3 * triangles;
  tinygltf::Primitive prim;
  if (draco_bits) {
    // KHR_draco_mesh_compression: one buffer view holds the Draco mesh; the accessors keep their
    // counts, types and bounds for viewers, without a buffer view of their own.
    tinygltf::BufferView compressed;
    compressed.buffer = 0;
    compressed.byteLength = draco_size;
    model.bufferViews = {compressed};
    pa.bufferView = -1;
    tinygltf::Value::Object attributes{{"POSITION", tinygltf::Value(0)}};
    tinygltf::Value::Object ext{{"bufferView", tinygltf::Value(0)}, {"attributes", tinygltf::Value(attributes)}};
    prim.extensions["KHR_draco_mesh_compression"] = tinygltf::Value(ext);
    model.extensionsUsed = model.extensionsRequired = {"KHR_draco_mesh_compression"};
  }
  prim.attributes["POSITION"] = 0;
  prim.mode = TINYGLTF_MODE_TRIANGLES;
  if (draco_bits) {
    // The Draco mesh holds the triangles; tinygltf refuses an indices accessor without a view.
    model.accessors = {pa};
  } else {
    model.accessors = {pa, ia};
    prim.indices = 1;
  }
  tinygltf::Mesh mesh;
  mesh.primitives.push_back(prim);
  model.meshes.push_back(mesh);
  tinygltf::Node node;
  node.mesh = 0;
  model.nodes.push_back(node);
  tinygltf::Scene scene;
  scene.nodes = {0};
  model.scenes.push_back(scene);
  model.defaultScene = 0;
  std::ostringstream out;
  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToStream(&model, out, false, binary))
    throw InputError(path, std::string("tinygltf could not write the ") + (binary ? "GLB" : "glTF"));
  return out.str();
}

}  // namespace mm::formats
