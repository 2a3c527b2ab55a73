// Offline commands working on files only, no store:
//   meshmark info MESH                      vertex and face counts
//   meshmark sample NAME OUT | --list       a generated CAD-like sample part
//   meshmark convert IN OUT                 a part in another mesh format
//   meshmark keygen OUT                     a random 256-bit customer key, mode 0600, never overwrites
// attack lives in attack_commands.cpp, embed and extract in mark_commands.cpp.
#include <sys/stat.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>

#include "cli/commands.h"
#include "cli/file_util.h"
#include "cli/key_file.h"
#include "cli/mesh_files.h"
#include "meshio/read_mesh.h"
#include "render/image.h"
#include "samples/part_family.h"
#include "samples/samples.h"
#include "cad/read_part.h"
#include "cad/sample_solids.h"
#include "support/atomic_file.h"

namespace mm::cli {
namespace {

std::string canonical_sample_name(std::string name) {
  std::replace(name.begin(), name.end(), '-', '_');
  return name;
}

void add_sample_command(CLI::App& app) {
  struct Args {
    std::string name, out;
    bool list = false;
    std::uint64_t variant = 0;
  };
  auto a = std::make_shared<Args>();
  auto* c = app.add_subcommand("sample", "Write a generated CAD-like sample part (closed, sharp-featured)");
  c->add_option("name", a->name, "part name (see --list); '-' and '_' are interchangeable");
  c->add_option("output", a->out,
                "file to write: a mesh (.off, .obj, .ply, .stl, ...), or for the CAD parts .step, .stp, .iges or .igs");
  c->add_flag("--list", a->list, "list the parts with their vertex and face counts");
  c->add_option("--variant", a->variant,
                "member of the part's family with seeded dimensions (0: the default part; mesh parts only)")
      ->capture_default_str();
  c->callback([a] {
    const auto parts = samples::sample_parts();
    if (a->list) {
      for (const auto& p : parts)
        std::cout << p.name << "  " << p.mesh.num_vertices() << " vertices, " << p.mesh.num_faces() << " faces\n";
      for (const auto& n : cad::sample_solid_names()) std::cout << n << "  CAD part (STEP or IGES)\n";
      return;
    }
    if (a->name.empty() || a->out.empty()) throw CLI::ValidationError("sample", "needs NAME and OUT (or --list)");
    const std::string name = canonical_sample_name(a->name);
    const auto& solids = cad::sample_solid_names();
    if (std::find(solids.begin(), solids.end(), name) != solids.end()) {
      const std::string ext = std::filesystem::path(a->out).extension().string();
      const std::string format = ext.empty() ? "" : ext.substr(1);
      if (!is_cad_format(format)) throw InputError(a->out, "a CAD sample is written as .step, .stp, .iges or .igs");
      if (a->variant != 0) throw CLI::ValidationError("--variant", "the CAD samples have no variants");
      const std::string bytes = cad::sample_solid_bytes(name, format);
      support::write_file_atomic(a->out, bytes);
      std::cout << a->out << ": " << name << ", " << bytes.size() << " bytes\n";
      return;
    }
    for (const auto& base : parts)
      if (base.name == name) {
        if (!is_mesh_path(a->out))
          throw InputError(a->out, "unknown output type (expected " + mesh_format_list() + ")");
        const samples::SamplePart p = samples::sample_variant(name, a->variant);
        write_mesh(p.mesh, a->out);
        std::cout << a->out << ": " << p.name << ", " << p.mesh.num_vertices() << " vertices, "
                  << p.mesh.num_faces() << " faces\n";
        return;
      }
    std::string names;
    for (const auto& p : parts) names += (names.empty() ? "" : ", ") + p.name;
    for (const auto& n : solids) names += ", " + n;
    throw CLI::ValidationError("sample", "unknown part '" + a->name + "' (known: " + names + ")");
  });
}

// A part in another mesh format: what a partner's tool does to a copy, and the benchmarks' converter.
void add_convert_command(CLI::App& app) {
  struct Args {
    std::string in, out, object;
    int draco_bits = 0;
  };
  auto a = std::make_shared<Args>();
  auto* c = app.add_subcommand("convert", "Write a part (a mesh, or a STEP or IGES part tessellated) in another mesh format");
  c->add_option("input", a->in, "part file (" + part_format_list() + ")")->required();
  c->add_option("output", a->out, "mesh file to write (" + mesh_format_list() + ")")->required();
  c->add_option("--draco-bits", a->draco_bits, "GLB or glTF output: Draco-compressed, positions quantised to these bits")
      ->check(CLI::Range(8, 30));
  c->add_option("--object", a->object, "3MF input: only the build items whose object has this name");
  c->callback([a] {
    if (!is_mesh_path(a->out)) throw InputError(a->out, "unknown output type (expected " + mesh_format_list() + ")");
    if (std::filesystem::weakly_canonical(a->in) == std::filesystem::weakly_canonical(a->out))
      throw CommandFailed(1, a->out + ": the output would overwrite the input");
    PartReport report;
    const Mesh m = read_part(a->in, {}, &report, ReadOptions{a->object});
    write_mesh(m, a->out, WriteOptions{report.read.unit, a->draco_bits, a->object});
    std::cout << a->out << ": " << m.num_vertices() << " vertices, " << m.num_faces() << " faces\n";
  });
}

// A line plot of a table, for the benchmarks: lines "series<TAB>x<TAB>y", '#' comments.
void add_plot_command(CLI::App& app) {
  struct Args {
    std::string in, out, title, x_label, y_label;
    double y_max = 0;
  };
  auto a = std::make_shared<Args>();
  auto* c = app.add_subcommand("plot", "Draw a line plot (PNG) of a table of series<TAB>x<TAB>y lines");
  c->add_option("table", a->in, "tab-separated lines: series name, x, y ('#' starts a comment)")->required();
  c->add_option("output", a->out, "PNG file to write")->required();
  c->add_option("--title", a->title, "plot title");
  c->add_option("--x-label", a->x_label, "x axis label");
  c->add_option("--y-label", a->y_label, "y axis label");
  c->add_option("--y-max", a->y_max, "clip the y axis at this value (0: from the data)")->check(kFiniteNumber);
  c->callback([a] {
    std::ifstream in(a->in);
    if (!in) throw InputError(a->in, "cannot be read");
    std::vector<PlotSeries> series;
    std::string line;
    for (int number = 1; std::getline(in, line); ++number) {
      if (line.empty() || line[0] == '#') continue;
      std::istringstream fields(line);
      std::string name, xs, ys;
      if (!std::getline(fields, name, '\t') || !std::getline(fields, xs, '\t') || !std::getline(fields, ys, '\t'))
        throw InputError(a->in, "line " + std::to_string(number) + ": expected series<TAB>x<TAB>y");
      double x = 0, y = 0;
      try {
        std::size_t used_x = 0, used_y = 0;
        x = std::stod(xs, &used_x);
        y = std::stod(ys, &used_y);
        if (used_x != xs.size() || used_y != ys.size()) throw std::invalid_argument("trailing characters");
      } catch (const std::exception&) {
        throw InputError(a->in, "line " + std::to_string(number) + ": x and y must be numbers");
      }
      auto it = std::find_if(series.begin(), series.end(), [&](const PlotSeries& s) { return s.label == name; });
      if (it == series.end()) {
        static const Rgb palette[] = {colours::blue, colours::red, colours::green, colours::orange,
                                      colours::purple, colours::black, colours::grey};
        PlotSeries s;
        s.label = name;
        s.colour = palette[series.size() % (sizeof palette / sizeof palette[0])];
        series.push_back(s);
        it = series.end() - 1;
      }
      it->points.emplace_back(x, a->y_max > 0 ? std::min(y, a->y_max) : y);
    }
    if (series.empty()) throw InputError(a->in, "no data lines");
    PlotOptions o;
    o.title = a->title;
    o.x_label = a->x_label;
    o.y_label = a->y_label;
    if (a->y_max > 0) o.y_min = 0, o.y_max = a->y_max;
    plot_lines(series, o).write_png(a->out);
    std::cout << a->out << ": " << series.size() << " series\n";
  });
}

void add_keygen_command(CLI::App& app) {
  auto out = std::make_shared<std::string>();
  auto* c = app.add_subcommand("keygen",
                               "Write a new random 256-bit customer key (hex, mode 0600); never overwrites, never prints the key");
  c->add_option("output", *out, "key file to create")->required();
  c->callback([out] {
    const Key key = generate_key();
    if (!write_file_exclusive(*out, key_file_text(key), 0600))
      throw CommandFailed(1, *out + ": exists; keygen never overwrites a key (remove it first if you really mean to)");
    std::cout << *out << ": new 256-bit key, mode 0600, fingerprint " << key_fingerprint(key) << "\n";
  });
}

}  // namespace

void add_offline_commands(CLI::App& app) {
  auto* info = app.add_subcommand("info", "Print vertex and face counts of a mesh");
  auto path = std::make_shared<std::string>();
  info->add_option("mesh", *path, "mesh file (STL, OBJ, OFF, PLY, 3MF, glTF, GLB) or CAD part (STEP, IGES)")->required();
  info->callback([path] {
    PartReport report;
    auto m = read_part(*path, {}, &report);
    std::cout << m.num_vertices() << " vertices, " << m.num_faces() << " faces";
    if (const auto& t = report.tessellation)
      std::cout << " (" << t->format << ": " << t->solids << " solid(s), " << t->faces
                << " faces tessellated by OpenCASCADE " << t->occt_version << " at " << t->linear_deflection_mm
                << " mm and " << t->options.angular_deflection_degrees << " degrees)";
    if (!report.read.object_names.empty()) {
      std::cout << " (3MF build items:";
      for (const auto& n : report.read.object_names) std::cout << " \"" << n << "\"";
      std::cout << ")";
    }
    std::cout << "\n";
  });
  add_sample_command(app);
  add_convert_command(app);
  add_keygen_command(app);
  add_plot_command(app);
  add_attack_commands(app);
  add_mark_commands(app);
}

}  // namespace mm::cli
