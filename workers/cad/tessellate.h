// STEP (AP203, AP214, AP242) and IGES parts as meshes, through OpenCASCADE: the file's shape
// read by its data-exchange readers (lengths converted to millimetres), every face of every
// solid, shell or loose face tessellated by BRepMesh_IncrementalMesh, and the faces' triangles
// joined into one mesh. A file with several solids is one part (one asset): its solids together.
//
// OpenCASCADE runs in a child process (300 s, 8 GiB), so a file that crashes or exhausts it is
// an InputError here, never a crash of the caller.
//
// The tessellation is deterministic for one OpenCASCADE version and the same options, so the
// options and tessellation_key() are recorded with an asset: detection and an evidence package
// years later redo the same mesh from the stored file.
#pragma once
#include <optional>
#include <string>
#include <string_view>

#include "meshio/mesh.h"

namespace mm {

struct TessellationOptions {
  // The largest distance between a triangle and the surface it stands for, as a fraction of the
  // part's bounding-box diagonal (a fraction keeps parts of any size alike).
  double linear_deflection = 0.0002;
  // The largest angle between neighbouring triangles' normals on a curved face, in degrees.
  double angular_deflection_degrees = 15;
};

struct Tessellation {
  std::string format;                    // "step" or "iges"
  std::string occt_version;              // the OpenCASCADE build that tessellated
  double linear_deflection_mm = 0;       // the absolute deflection used
  TessellationOptions options;
  int solids = 0;                        // solids in the file
  int faces = 0;                         // B-rep faces tessellated
  int degenerate_triangles_dropped = 0;  // triangles whose corners coincide
};

// "step", "stp", "iges", "igs": the formats tessellate_cad reads.
bool is_cad_format(const std::string& extension);
// The OpenCASCADE version this build runs ("7.6.3").
std::string occt_version();
// The options and the OpenCASCADE version as one text, for cache keys and records.
std::string tessellation_key(const TessellationOptions& options);
// The options a key made by tessellation_key records, found anywhere in `text` (a preparation
// key ends with it); nullopt when it holds none or they do not parse.
std::optional<TessellationOptions> tessellation_options_in(const std::string& text);

// The part in `bytes` (format: one of is_cad_format's), tessellated. Vertices are numbered in
// order of first appearance over the faces in the file's order; coordinates equal to the last
// bit are one vertex, so faces meeting along an edge share its vertices. Throws
// InputError(source, reason) for a file OpenCASCADE cannot read, a file with no surface, a
// tessellation with no triangle, or options out of range.
Mesh tessellate_cad(std::string_view bytes, const std::string& format, const std::string& source,
                    const TessellationOptions& options = {}, Tessellation* info = nullptr);

}  // namespace mm
