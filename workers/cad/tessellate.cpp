#include "cad/tessellate.h"

#include <BRepBndLib.hxx>
#include <BRepMesh_IncrementalMesh.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <IGESControl_Reader.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <Message_PrinterOStream.hxx>
#include <Poly_Triangulation.hxx>
#include <STEPControl_Reader.hxx>
#include <Standard_Failure.hxx>
#include <Standard_Version.hxx>
#include <TopExp_Explorer.hxx>
#include <TopLoc_Location.hxx>
#include <TopTools_MapOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Face.hxx>
#include <TopoDS_Shape.hxx>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <unistd.h>

#include "cad/occt_lock.h"
#include "meshio/read_mesh.h"

namespace mm {

std::mutex& cad::occt_mutex() {
  static std::mutex m;
  return m;
}

void cad::silence_occt() {
  static std::once_flag once;
  std::call_once(once, [] { Message::DefaultMessenger()->ChangePrinters().Clear(); });
}

namespace {

// Beyond this many triangles a tessellation is not a part meshmark processes (as for 3MF).
constexpr long long kMaxTriangles = 100'000'000;

std::string canonical(const std::string& format) {
  if (format == "step" || format == "stp") return "step";
  if (format == "iges" || format == "igs") return "iges";
  return "";
}

// IGESControl_Reader reads files only: the bytes go to a private temporary file, removed after.
class TempFile {
 public:
  TempFile(std::string_view bytes, const std::string& source) {
    std::string pattern = (std::filesystem::temp_directory_path() / "meshmark-cad-XXXXXX").string();
    const int fd = ::mkstemp(pattern.data());
    if (fd < 0) throw InputError(source, "cannot make a temporary file to read the IGES part");
    path_ = pattern;
    std::size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
      if (n <= 0) {
        ::close(fd);
        std::remove(path_.c_str());
        throw InputError(source, "cannot write a temporary file to read the IGES part");
      }
      done += static_cast<std::size_t>(n);
    }
    ::close(fd);
  }
  ~TempFile() { std::remove(path_.c_str()); }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

TopoDS_Shape read_shape(std::string_view bytes, const std::string& format, const std::string& source) {
  if (format == "step") {
    STEPControl_Reader reader;
    std::istringstream in{std::string(bytes)};
    if (reader.ReadStream(source.c_str(), in) != IFSelect_RetDone)
      throw InputError(source, "not a readable STEP file (OpenCASCADE's reader refused it)");
    if (reader.TransferRoots() == 0) throw InputError(source, "the STEP file holds no shape OpenCASCADE can transfer");
    return reader.OneShape();
  }
  const TempFile file(bytes, source);
  IGESControl_Reader reader;
  if (reader.ReadFile(file.path().c_str()) != IFSelect_RetDone)
    throw InputError(source, "not a readable IGES file (OpenCASCADE's reader refused it)");
  if (reader.TransferRoots() == 0) throw InputError(source, "the IGES file holds no shape OpenCASCADE can transfer");
  return reader.OneShape();
}

Mesh triangles_of(const TopoDS_Shape& shape, const std::string& source, Tessellation* info) {
  std::map<std::array<double, 3>, int> index;  // exact coordinates -> vertex
  std::vector<std::array<double, 3>> points;
  Mesh mesh;
  TopTools_MapOfShape seen;
  for (TopExp_Explorer ex(shape, TopAbs_FACE); ex.More(); ex.Next()) {
    const TopoDS_Face& face = TopoDS::Face(ex.Current());
    if (!seen.Add(face)) continue;  // a face shared by two solids of a compound
    ++info->faces;
    TopLoc_Location location;
    const Handle(Poly_Triangulation) tri = BRep_Tool::Triangulation(face, location);
    if (tri.IsNull()) continue;
    if (static_cast<long long>(mesh.faces.size()) + tri->NbTriangles() > kMaxTriangles)
      throw InputError(source, "the tessellation has more than " + std::to_string(kMaxTriangles) + " triangles");
    const gp_Trsf transform = location.Transformation();
    std::vector<int> id(static_cast<std::size_t>(tri->NbNodes()) + 1, -1);
    for (int i = 1; i <= tri->NbNodes(); ++i) {
      gp_Pnt p = tri->Node(i);
      if (!location.IsIdentity()) p.Transform(transform);
      // + 0.0 makes -0 and +0 one key.
      const std::array<double, 3> key{p.X() + 0.0, p.Y() + 0.0, p.Z() + 0.0};
      if (!std::isfinite(key[0]) || !std::isfinite(key[1]) || !std::isfinite(key[2]))
        throw InputError(source, "the tessellation has a non-finite coordinate");
      const auto [it, added] = index.emplace(key, static_cast<int>(points.size()));
      if (added) points.push_back(key);
      id[static_cast<std::size_t>(i)] = it->second;
    }
    const bool reversed = face.Orientation() == TopAbs_REVERSED;
    for (int t = 1; t <= tri->NbTriangles(); ++t) {
      int a = 0, b = 0, c = 0;
      tri->Triangle(t).Get(a, b, c);
      if (a < 1 || b < 1 || c < 1 || a > tri->NbNodes() || b > tri->NbNodes() || c > tri->NbNodes())
        throw InputError(source, "the tessellation has a triangle index out of range");
      if (reversed) std::swap(b, c);
      const int va = id[static_cast<std::size_t>(a)], vb = id[static_cast<std::size_t>(b)],
                vc = id[static_cast<std::size_t>(c)];
      if (va == vb || vb == vc || va == vc) {
        ++info->degenerate_triangles_dropped;
        continue;
      }
      mesh.faces.push_back({va, vb, vc});
    }
  }
  if (mesh.faces.empty()) throw InputError(source, "the " + info->format + " part tessellates to no triangle");
  mesh.points.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t i = 0; i < points.size(); ++i)
    for (int k = 0; k < 3; ++k) mesh.points(static_cast<Eigen::Index>(i), k) = points[i][static_cast<std::size_t>(k)];
  return mesh;
}

}  // namespace

bool is_cad_format(const std::string& extension) { return !canonical(extension).empty(); }

std::string occt_version() { return OCC_VERSION_COMPLETE; }

std::string tessellation_key(const TessellationOptions& options) {
  return "occt=" + occt_version() + ";linear=" + shortest_text(options.linear_deflection) +
         ";angular=" + shortest_text(options.angular_deflection_degrees);
}

Mesh tessellate_cad(std::string_view bytes, const std::string& format, const std::string& source,
                    const TessellationOptions& options, Tessellation* info) {
  Tessellation local;
  Tessellation& out = info ? *info : local;
  out = Tessellation{};
  out.format = canonical(format);
  out.occt_version = occt_version();
  out.options = options;
  if (out.format.empty()) throw InputError(source, "unknown CAD format \"" + format + "\" (expected step, stp, iges or igs)");
  if (!(options.linear_deflection > 0 && options.linear_deflection <= 0.1))
    throw InputError(source, "linear deflection " + shortest_text(options.linear_deflection) +
                                 " is outside (0, 0.1] of the diagonal");
  if (!(options.angular_deflection_degrees >= 1 && options.angular_deflection_degrees <= 90))
    throw InputError(source, "angular deflection " + shortest_text(options.angular_deflection_degrees) +
                                 " degrees is outside [1, 90]");
  if (bytes.empty()) throw InputError(source, "empty file");
  const std::lock_guard<std::mutex> lock(cad::occt_mutex());
  cad::silence_occt();
  try {
    const TopoDS_Shape shape = read_shape(bytes, out.format, source);
    if (shape.IsNull()) throw InputError(source, "the " + out.format + " file holds no shape");
    for (TopExp_Explorer ex(shape, TopAbs_SOLID); ex.More(); ex.Next()) ++out.solids;
    Bnd_Box box;
    BRepBndLib::Add(shape, box);
    if (box.IsVoid()) throw InputError(source, "the " + out.format + " file holds no surface");
    double x0, y0, z0, x1, y1, z1;
    box.Get(x0, y0, z0, x1, y1, z1);
    const double diagonal = std::sqrt((x1 - x0) * (x1 - x0) + (y1 - y0) * (y1 - y0) + (z1 - z0) * (z1 - z0));
    if (!(diagonal > 0) || !std::isfinite(diagonal))
      throw InputError(source, "the " + out.format + " part has no extent (bounding box " + shortest_text(diagonal) + ")");
    out.linear_deflection_mm = options.linear_deflection * diagonal;
    // Sequential meshing: the same triangles on every run.
    const BRepMesh_IncrementalMesh mesher(shape, out.linear_deflection_mm, Standard_False,
                                          options.angular_deflection_degrees * M_PI / 180, Standard_False);
    if (!mesher.IsDone()) throw InputError(source, "OpenCASCADE could not tessellate the " + out.format + " part");
    return triangles_of(shape, source, &out);
  } catch (const Standard_Failure& e) {
    const char* what = e.GetMessageString();
    throw InputError(source, std::string("OpenCASCADE failed on the ") + out.format + " file: " +
                                 (what && *what ? what : e.DynamicType()->Name()));
  }
}

}  // namespace mm
