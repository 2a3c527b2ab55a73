#include "cad/tessellate.h"

#include <BRepBndLib.hxx>
#include <BRepMesh_IncrementalMesh.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <IGESControl_Reader.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
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
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <functional>
#include <optional>

#include "cad/occt_lock.h"
#include "meshio/read_mesh.h"

#if defined(__SANITIZE_ADDRESS__)
#define MM_ADDRESS_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MM_ADDRESS_SANITIZER 1
#endif
#endif
#ifndef MM_ADDRESS_SANITIZER
#define MM_ADDRESS_SANITIZER 0
#endif

// Present only in sanitized builds.
extern "C" void __sanitizer_set_death_callback(void (*)(void)) __attribute__((weak));

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

// iges_path: the bytes in a file, for IGES (made by the parent process, so a crash leaves none).
TopoDS_Shape read_shape(std::string_view bytes, const std::string& format, const std::string& source,
                        const std::string& iges_path) {
  if (format == "step") {
    STEPControl_Reader reader;
    std::istringstream in{std::string(bytes)};
    if (reader.ReadStream(source.c_str(), in) != IFSelect_RetDone)
      throw InputError(source, "not a readable STEP file (OpenCASCADE's reader refused it)");
    if (reader.TransferRoots() == 0) throw InputError(source, "the STEP file holds no shape OpenCASCADE can transfer");
    return reader.OneShape();
  }
  IGESControl_Reader reader;
  if (reader.ReadFile(iges_path.c_str()) != IFSelect_RetDone)
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


// The OpenCASCADE work itself, in the child process.
Mesh tessellate_here(std::string_view bytes, const std::string& source, const TessellationOptions& options,
                     const std::string& iges_path, Tessellation& out) {
  cad::silence_occt();
  try {
    const TopoDS_Shape shape = read_shape(bytes, out.format, source, iges_path);
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

template <class T>
void put(std::string& s, const T& v) {
  s.append(reinterpret_cast<const char*>(&v), sizeof v);
}
template <class T>
T take(std::string_view& s, const std::string& source) {
  if (s.size() < sizeof(T)) throw InputError(source, "the OpenCASCADE reader process sent a truncated result");
  T v;
  std::memcpy(&v, s.data(), sizeof v);
  s.remove_prefix(sizeof v);
  return v;
}

// 'M', the counts, the points, the triangles and the tessellation's numbers; or 'E' and a reason.
std::string encode_result(const Mesh& m, const Tessellation& t) {
  std::string s = "M";
  put(s, static_cast<std::int64_t>(m.num_vertices()));
  put(s, static_cast<std::int64_t>(m.num_faces()));
  s.append(reinterpret_cast<const char*>(m.points.data()), sizeof(double) * static_cast<std::size_t>(m.points.size()));
  for (const auto& f : m.faces)
    for (int v : f) put(s, static_cast<std::int32_t>(v));
  put(s, static_cast<std::int32_t>(t.solids));
  put(s, static_cast<std::int32_t>(t.faces));
  put(s, static_cast<std::int32_t>(t.degenerate_triangles_dropped));
  put(s, t.linear_deflection_mm);
  return s;
}

Mesh decode_result(const std::string& reply, const std::string& source, Tessellation& t) {
  std::string_view s(reply);
  if (s.empty()) throw InputError(source, "the OpenCASCADE reader process sent no result");
  const char kind = s.front();
  s.remove_prefix(1);
  if (kind == 'E') throw InputError(source, std::string(s));
  if (kind != 'M') throw InputError(source, "the OpenCASCADE reader process sent a malformed result");
  const auto nv = take<std::int64_t>(s, source), nf = take<std::int64_t>(s, source);
  if (nv < 0 || nf < 0 || static_cast<std::uint64_t>(nv) * 24 + static_cast<std::uint64_t>(nf) * 12 > s.size())
    throw InputError(source, "the OpenCASCADE reader process sent a malformed result");
  Mesh m;
  m.points.resize(nv, 3);
  std::memcpy(m.points.data(), s.data(), sizeof(double) * static_cast<std::size_t>(nv) * 3);
  s.remove_prefix(sizeof(double) * static_cast<std::size_t>(nv) * 3);
  m.faces.resize(static_cast<std::size_t>(nf));
  for (auto& f : m.faces) f = {take<std::int32_t>(s, source), take<std::int32_t>(s, source), take<std::int32_t>(s, source)};
  t.solids = take<std::int32_t>(s, source);
  t.faces = take<std::int32_t>(s, source);
  t.degenerate_triangles_dropped = take<std::int32_t>(s, source);
  t.linear_deflection_mm = take<double>(s, source);
  check_mesh(m, source);
  return m;
}

// OpenCASCADE's readers crash on some hostile files (a STEP edge that refers to itself recurses
// until the stack overflows) and can take any time and memory: each file is read in a child
// process with a time and memory limit, and a child that dies is an InputError, not a crash.
constexpr unsigned kChildSeconds = 300;
constexpr rlim_t kChildBytes = rlim_t{8} << 30;

std::string in_child_process(const std::string& source, const std::function<std::string()>& work) {
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) throw InputError(source, "cannot start the OpenCASCADE reader process (pipe)");
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    throw InputError(source, "cannot start the OpenCASCADE reader process (fork)");
  }
  if (pid == 0) {
    ::close(fds[0]);
    // Under libFuzzer, a dying child must not report as the fuzzer's own process.
    if (&__sanitizer_set_death_callback) __sanitizer_set_death_callback(nullptr);
#if !MM_ADDRESS_SANITIZER
    const rlimit memory{kChildBytes, kChildBytes};  // ASan reserves far more address space than it uses
    ::setrlimit(RLIMIT_AS, &memory);
#endif
    ::alarm(kChildSeconds);
    std::string reply;
    try {
      reply = work();
    } catch (const InputError& e) {
      reply = "E" + e.reason();
    } catch (const std::bad_alloc&) {
      reply = "Ereading it needed more than " + std::to_string(kChildBytes >> 30) + " GiB of memory";
    } catch (const std::exception& e) {
      reply = std::string("EOpenCASCADE failed on it: ") + e.what();
    } catch (...) {
      reply = "EOpenCASCADE failed on it";
    }
    std::size_t done = 0;
    while (done < reply.size()) {
      const ssize_t n = ::write(fds[1], reply.data() + done, reply.size() - done);
      if (n <= 0 && errno != EINTR) ::_exit(3);
      if (n > 0) done += static_cast<std::size_t>(n);
    }
    ::_exit(0);
  }
  ::close(fds[1]);
  std::string reply;
  char buffer[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fds[0], buffer, sizeof buffer);
    if (n > 0) reply.append(buffer, static_cast<std::size_t>(n));
    else if (n == 0 || errno != EINTR) break;
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFSIGNALED(status)) {
    const int sig = WTERMSIG(status);
    if (sig == SIGALRM) throw InputError(source, "OpenCASCADE took longer than " + std::to_string(kChildSeconds) + " s to read it");
    throw InputError(source, std::string("OpenCASCADE crashed reading it (signal ") + std::to_string(sig) + ", " +
                                 ::strsignal(sig) + ")");
  }
  // A sanitizer's report ends the child with an exit status instead of the signal.
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw InputError(source, "OpenCASCADE crashed reading it (exit status " + std::to_string(WEXITSTATUS(status)) + ")");
  return reply;
}

}  // namespace

bool is_cad_format(const std::string& extension) { return !canonical(extension).empty(); }

std::string occt_version() { return OCC_VERSION_COMPLETE; }

std::string tessellation_key(const TessellationOptions& options) {
  return "occt=" + occt_version() + ";linear=" + shortest_text(options.linear_deflection) +
         ";angular=" + shortest_text(options.angular_deflection_degrees);
}

std::optional<TessellationOptions> tessellation_options_in(const std::string& text) {
  const size_t at = text.find("occt=");
  if (at == std::string::npos) return std::nullopt;
  auto number = [&](const std::string& name) -> std::optional<double> {
    const size_t k = text.find(";" + name + "=", at);
    if (k == std::string::npos) return std::nullopt;
    const char* begin = text.c_str() + k + name.size() + 2;
    char* end = nullptr;
    const double v = std::strtod(begin, &end);
    if (end == begin || !std::isfinite(v) || !(v > 0)) return std::nullopt;
    return v;
  };
  const auto linear = number("linear"), angular = number("angular");
  if (!linear || !angular) return std::nullopt;
  return TessellationOptions{*linear, *angular};
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
  std::optional<TempFile> iges;
  if (out.format == "iges") iges.emplace(bytes, source);
  const std::string reply = in_child_process(source, [&] {
    Tessellation t = out;
    const Mesh m = tessellate_here(bytes, source, options, iges ? iges->path() : std::string(), t);
    return encode_result(m, t);
  });
  return decode_result(reply, source, out);
}
}  // namespace mm
