// 3MF (3D Manufacturing Format) through lib3mf, Debian's lib3mf-dev (version 1.x, C interface).
// Reading takes every build item (or those whose object has a chosen name): its object's meshes,
// through components (nested up to kMaxComponentDepth), with the item's and the components'
// transforms applied, concatenated into one mesh in build order. The model's unit is reported (ReadReport::unit) and coordinates stay
// in it. 3MF stores coordinates as 32-bit floats; writing rounds to them as binary STL does.
#include <Model/COM/NMR_DLLInterfaces.h>

#include <algorithm>
#include <iterator>
#include <limits>
#include <memory>

#include "meshio/formats.h"

namespace mm::formats {
namespace {

constexpr int kMaxComponentDepth = 16;
// Beyond this many vertices or triangles in all, a part is not a CAD part meshmark processes.
constexpr long long kMaxCount = 100'000'000;

const char* const kUnits[] = {"micron", "millimeter", "centimeter", "inch", "foot", "meter"};

struct Release {
  void operator()(NMR::PLib3MFBase* p) const { NMR::lib3mf_release(p); }
};
template <class T>
using Handle = std::unique_ptr<T, Release>;

std::string last_error(NMR::PLib3MFBase* where) {
  DWORD code = 0;
  LPCSTR message = nullptr;
  if (where && NMR::lib3mf_getlasterror(where, &code, &message) == LIB3MF_OK && message && *message) return message;
  return "lib3mf error";
}

// The 3 x 4 affine map p -> A p + t of a lib3mf transform (m_fFields[row][column], column 3 = t).
using Affine = Eigen::Matrix<double, 3, 4>;
Affine affine(const NMR::MODELTRANSFORM& t) {
  Affine a;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 4; ++j) a(i, j) = t.m_fFields[i][j];
  return a;
}
Affine compose(const Affine& outer, const Affine& inner) {  // outer(inner(p))
  Affine c;
  c.leftCols<3>() = outer.leftCols<3>() * inner.leftCols<3>();
  c.col(3) = outer.leftCols<3>() * inner.col(3) + outer.col(3);
  return c;
}

struct Collector {
  const std::string& source;
  std::vector<Eigen::Vector3d> points;
  std::vector<std::vector<int>> faces;

  void fail(const std::string& why) const { throw InputError(source, why); }

  void add(NMR::PLib3MFModelObjectResource* object, const Affine& to_world, int depth) {
    BOOL is_mesh = false, is_components = false;
    if (NMR::lib3mf_object_ismeshobject(object, &is_mesh) != LIB3MF_OK ||
        NMR::lib3mf_object_iscomponentsobject(object, &is_components) != LIB3MF_OK)
      fail("3MF object: " + last_error(object));
    if (is_mesh) {
      add_mesh(object, to_world);
    } else if (is_components) {
      if (depth >= kMaxComponentDepth)
        fail("3MF components nested deeper than " + std::to_string(kMaxComponentDepth) + " levels");
      DWORD count = 0;
      if (NMR::lib3mf_componentsobject_getcomponentcount(object, &count) != LIB3MF_OK)
        fail("3MF components: " + last_error(object));
      for (DWORD i = 0; i < count; ++i) {
        NMR::PLib3MFModelComponent* raw = nullptr;
        if (NMR::lib3mf_componentsobject_getcomponent(object, i, &raw) != LIB3MF_OK) fail("3MF component: " + last_error(object));
        Handle<NMR::PLib3MFModelComponent> component(raw);
        NMR::PLib3MFModelObjectResource* child_raw = nullptr;
        NMR::MODELTRANSFORM t{};
        if (NMR::lib3mf_component_getobjectresource(raw, &child_raw) != LIB3MF_OK ||
            NMR::lib3mf_component_gettransform(raw, &t) != LIB3MF_OK)
          fail("3MF component: " + last_error(raw));
        Handle<NMR::PLib3MFModelObjectResource> child(child_raw);
        add(child_raw, compose(to_world, affine(t)), depth + 1);
      }
    }
  }

  void add_mesh(NMR::PLib3MFModelObjectResource* object, const Affine& to_world) {
    DWORD nv = 0, nt = 0;
    if (NMR::lib3mf_meshobject_getvertexcount(object, &nv) != LIB3MF_OK ||
        NMR::lib3mf_meshobject_gettrianglecount(object, &nt) != LIB3MF_OK)
      fail("3MF mesh: " + last_error(object));
    if (static_cast<long long>(points.size()) + nv > kMaxCount || static_cast<long long>(faces.size()) + nt > kMaxCount)
      fail("3MF model has more than " + std::to_string(kMaxCount) + " vertices or triangles");
    std::vector<NMR::MODELMESHVERTEX> v(nv);
    std::vector<NMR::MODELMESHTRIANGLE> t(nt);
    DWORD got_v = 0, got_t = 0;
    if ((nv && NMR::lib3mf_meshobject_getvertices(object, v.data(), nv, &got_v) != LIB3MF_OK) ||
        (nt && NMR::lib3mf_meshobject_gettriangleindices(object, t.data(), nt, &got_t) != LIB3MF_OK) ||
        got_v != nv || got_t != nt)
      fail("3MF mesh: " + last_error(object));
    const int base = static_cast<int>(points.size());
    for (DWORD i = 0; i < nv; ++i) {
      const Eigen::Vector3d p(v[i].m_fPosition[0], v[i].m_fPosition[1], v[i].m_fPosition[2]);
      const Eigen::Vector3d q = to_world.leftCols<3>() * p + to_world.col(3);
      check_finite(q.data(), source, "3MF vertex " + std::to_string(points.size()));
      points.push_back(q);
    }
    for (DWORD i = 0; i < nt; ++i) {
      std::vector<int> f(3);
      for (int k = 0; k < 3; ++k) {
        if (t[i].m_nIndices[k] >= nv)
          fail("3MF triangle " + std::to_string(i) + " index " + std::to_string(t[i].m_nIndices[k]) + " out of range (" +
               std::to_string(nv) + " vertices)");
        f[k] = base + static_cast<int>(t[i].m_nIndices[k]);
      }
      faces.push_back(std::move(f));
    }
  }
};

std::string object_name(NMR::PLib3MFModelObjectResource* object, const std::string& source) {
  ULONG needed = 0;
  if (NMR::lib3mf_object_getnameutf8(object, nullptr, 0, &needed) != LIB3MF_OK)
    throw InputError(source, "3MF object name: " + last_error(object));
  if (needed > 4096) throw InputError(source, "3MF object name longer than 4096 bytes");
  std::string name(needed + 1, '\0');
  if (NMR::lib3mf_object_getnameutf8(object, name.data(), needed + 1, &needed) != LIB3MF_OK)
    throw InputError(source, "3MF object name: " + last_error(object));
  name.resize(std::min<std::size_t>(needed, name.size()));
  while (!name.empty() && name.back() == '\0') name.pop_back();
  return name;
}

}  // namespace

Mesh parse_3mf(std::string_view bytes, const std::string& source, ReadReport& report, const std::string& object) {
  report.format = "3mf";
  NMR::PLib3MFModel* model_raw = nullptr;
  if (NMR::lib3mf_createmodel(&model_raw) != LIB3MF_OK) throw InputError(source, "lib3mf could not create a model");
  Handle<NMR::PLib3MFModel> model(model_raw);
  NMR::PLib3MFModelReader* reader_raw = nullptr;
  if (NMR::lib3mf_model_queryreader(model_raw, "3mf", &reader_raw) != LIB3MF_OK)
    throw InputError(source, "lib3mf has no 3MF reader: " + last_error(model_raw));
  Handle<NMR::PLib3MFModelReader> reader(reader_raw);
  std::vector<BYTE> buffer(bytes.begin(), bytes.end());  // lib3mf wants a mutable buffer
  if (NMR::lib3mf_reader_readfrombuffer(reader_raw, buffer.data(), buffer.size()) != LIB3MF_OK)
    throw InputError(source, "not a readable 3MF file: " + last_error(reader_raw));
  DWORD unit = 1;
  if (NMR::lib3mf_model_getunit(model_raw, &unit) != LIB3MF_OK || unit >= std::size(kUnits))
    throw InputError(source, "3MF model has an unknown unit");
  report.unit = kUnits[unit];

  Collector c{source, {}, {}};
  NMR::PLib3MFModelBuildItemIterator* items_raw = nullptr;
  if (NMR::lib3mf_model_getbuilditems(model_raw, &items_raw) != LIB3MF_OK)
    throw InputError(source, "3MF build: " + last_error(model_raw));
  Handle<NMR::PLib3MFModelBuildItemIterator> items(items_raw);
  int count = 0;
  report.objects = 0;
  for (BOOL more = false; NMR::lib3mf_builditemiterator_movenext(items_raw, &more) == LIB3MF_OK && more;) {
    NMR::PLib3MFModelBuildItem* item_raw = nullptr;
    if (NMR::lib3mf_builditemiterator_getcurrent(items_raw, &item_raw) != LIB3MF_OK)
      throw InputError(source, "3MF build item: " + last_error(items_raw));
    Handle<NMR::PLib3MFModelBuildItem> item(item_raw);
    NMR::PLib3MFModelObjectResource* object_raw = nullptr;
    NMR::MODELTRANSFORM t{};
    if (NMR::lib3mf_builditem_getobjectresource(item_raw, &object_raw) != LIB3MF_OK ||
        NMR::lib3mf_builditem_getobjecttransform(item_raw, &t) != LIB3MF_OK)
      throw InputError(source, "3MF build item " + std::to_string(count) + ": " + last_error(item_raw));
    Handle<NMR::PLib3MFModelObjectResource> held(object_raw);
    const std::string name = object_name(object_raw, source);
    report.object_names.push_back(name);
    ++count;
    if (!object.empty() && name != object) continue;
    c.add(object_raw, affine(t), 0);
    ++report.objects;
  }
  if (count == 0) throw InputError(source, "3MF model has no build items (nothing to make)");
  if (report.objects == 0) {
    std::string names;
    for (const auto& n : report.object_names) names += (names.empty() ? "\"" : ", \"") + n + "\"";
    throw InputError(source, "no 3MF build item holds an object named \"" + object + "\" (objects: " + names + ")");
  }
  Mesh m;
  m.points.resize(static_cast<Eigen::Index>(c.points.size()), 3);
  for (std::size_t i = 0; i < c.points.size(); ++i) m.points.row(static_cast<Eigen::Index>(i)) = c.points[i].transpose();
  m.faces = std::move(c.faces);
  return m;
}

std::string three_mf_bytes(const std::vector<std::pair<std::string, Mesh>>& objects, const std::string& unit,
                           const std::string& path) {
  DWORD unit_code = 1;  // millimeter, 3MF's default
  if (!unit.empty()) {
    const auto* it = std::find(std::begin(kUnits), std::end(kUnits), unit);
    if (it == std::end(kUnits)) throw InputError(path, "unknown 3MF unit \"" + unit + "\"");
    unit_code = static_cast<DWORD>(it - std::begin(kUnits));
  }
  NMR::PLib3MFModel* model_raw = nullptr;
  if (NMR::lib3mf_createmodel(&model_raw) != LIB3MF_OK) throw InputError(path, "lib3mf could not create a model");
  Handle<NMR::PLib3MFModel> model(model_raw);
  if (NMR::lib3mf_model_setunit(model_raw, unit_code) != LIB3MF_OK) throw InputError(path, "3MF: " + last_error(model_raw));
  for (const auto& [name, m] : objects) {
    std::vector<NMR::MODELMESHVERTEX> v(static_cast<std::size_t>(m.num_vertices()));
    for (int i = 0; i < m.num_vertices(); ++i)
      for (int k = 0; k < 3; ++k) v[i].m_fPosition[k] = static_cast<float>(m.points(i, k));
    std::vector<NMR::MODELMESHTRIANGLE> t;
    for (const auto& f : m.faces)
      for (std::size_t k = 1; k + 1 < f.size(); ++k)  // fan triangulation keeps the orientation
        t.push_back({{static_cast<DWORD>(f[0]), static_cast<DWORD>(f[k]), static_cast<DWORD>(f[k + 1])}});
    if (t.size() > std::numeric_limits<DWORD>::max()) throw InputError(path, "too many triangles for 3MF");
    NMR::PLib3MFModelMeshObject* mesh_raw = nullptr;
    NMR::PLib3MFModelBuildItem* item_raw = nullptr;
    if (NMR::lib3mf_model_addmeshobject(model_raw, &mesh_raw) != LIB3MF_OK)
      throw InputError(path, "3MF: " + last_error(model_raw));
    Handle<NMR::PLib3MFModelMeshObject> mesh(mesh_raw);
    if ((!name.empty() && NMR::lib3mf_object_setnameutf8(mesh_raw, name.c_str()) != LIB3MF_OK) ||
        NMR::lib3mf_meshobject_setgeometry(mesh_raw, v.data(), static_cast<DWORD>(v.size()), t.data(),
                                           static_cast<DWORD>(t.size())) != LIB3MF_OK ||
        NMR::lib3mf_model_addbuilditem(model_raw, mesh_raw, nullptr, &item_raw) != LIB3MF_OK)
      throw InputError(path, "3MF: " + last_error(mesh_raw));
    Handle<NMR::PLib3MFModelBuildItem> item(item_raw);
  }
  NMR::PLib3MFModelWriter* writer_raw = nullptr;
  if (NMR::lib3mf_model_querywriter(model_raw, "3mf", &writer_raw) != LIB3MF_OK)
    throw InputError(path, "lib3mf has no 3MF writer: " + last_error(model_raw));
  Handle<NMR::PLib3MFModelWriter> writer(writer_raw);
  ULONG64 size = 0;
  if (NMR::lib3mf_writer_getstreamsize(writer_raw, &size) != LIB3MF_OK)
    throw InputError(path, "3MF: " + last_error(writer_raw));
  std::string out(static_cast<std::size_t>(size), '\0');
  if (NMR::lib3mf_writer_writetobuffer(writer_raw, reinterpret_cast<BYTE*>(out.data()), size) != LIB3MF_OK)
    throw InputError(path, "3MF: " + last_error(writer_raw));
  return out;
}

std::string three_mf_bytes(const Mesh& mesh, const std::string& unit, const std::string& path,
                           const std::string& object_name) {
  const std::vector<std::pair<std::string, Mesh>> one{{object_name, mesh}};
  return three_mf_bytes(one, unit, path);
}

}  // namespace mm::formats
