// The one compression entry point: `meshmark compress` (default and --fast) and protect jobs
// both call fit_part(), the command then compress_part() for its stream.
//
// fit_part fits the part at each angle whose crease network differs from the earlier angles'
// (the same network gives the same fit); when none meets the tolerance, the fallback angles are
// fitted in turn until one does, then the closest goes on to the budget, on a finer split of the
// part where its own vertices run out (PartOptions::extend, max_splits). Every round is checked by the dense measurement (the one
// `meshmark compare` reports) unless the caller supplies its own check. compress_part then
// searches the smallest stream among the polyhedra that met the tolerance (smallest_stream.h).
#pragma once
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "compression/smallest_stream.h"
#include "fitting/compress.h"

namespace mm {

// Runs task(0) .. task(n - 1), at most `at_once` at a time, and returns when all are done. The
// tasks are independent; the caller decides whether threads run them (the library starts none).
using ParallelFor = std::function<void(int n, int at_once, const std::function<void(int)>& task)>;

struct PartOptions {
  CompressOptions fit;  // fit.angle_degrees is ignored: `angles` says which
  std::vector<double> angles{35.0};
  std::vector<double> fallback_angles;  // tried in turn while no fit meets the tolerance
  // When no angle meets the tolerance in fit.max_rounds, the closest fit goes on until the
  // tolerance or the budget (every round grows the polyhedron by 15 % or more, so the budget ends
  // them): a tight tolerance needs more growth steps than the first rounds give. Off: no more rounds.
  bool extend = true;
  // When that fit holds every vertex of the part below the budget (a coarse tessellation: a
  // subdivision surface through its vertices rounds its facets off), the part split at its edges'
  // midpoints (the same surface, four times the faces) is fitted again, up to this many times.
  int max_splits = 2;
  int at_once = 1;       // fits of the angles run at once (through `parallel`)
  ParallelFor parallel;  // empty: one after another on this thread
  StreamSearch stream;   // compress_part only; tolerance and levels are taken from `fit`
};

struct FitAtAngle {
  double angle = 0;
  CompressResult result;
  std::shared_ptr<const CompressState> rounds;  // for the coarsening (compress_rounds)
  bool coarsened = false;
};

struct PartFits {
  std::vector<FitAtAngle> fits;  // one per distinct crease network, angles first, then fallbacks
  std::vector<double> refused;   // angles at which compress() refused the part
  // Every fit's candidates that met the tolerance, fewest vertices first, with their fit.
  std::vector<std::pair<const FitAtAngle*, const Mesh*>> polyhedra;
  double cpu_seconds = 0;  // of the fits, summed over the threads that ran them
  int threads = 1;         // the most fits that ran at once
  // The fit a protect job keeps: the first that met the tolerance, else the closest.
  const FitAtAngle& kept() const;
};

// Refusals (InputError) of every angle: the first is thrown. A fallback angle that fails
// otherwise (a singular fit) is passed over too; std::bad_alloc always propagates.
// With fit.coarsen, only the fit whose rounds met the tolerance with the fewest vertices is
// coarsened (the angles' rounds foretell the coarsening's winner).
PartFits fit_part(const Mesh& part, const MeasuredSurface& measured, const PartOptions& options,
                  const std::string& source);

struct CompressedPart {
  PartFits fits;
  ChosenStream stream;
  const FitAtAngle* fit = nullptr;  // the chosen polyhedron's fit
  const Mesh* control = nullptr;    // the chosen polyhedron
  int candidates = 0;               // polyhedra the stream search weighed
  double stream_seconds = 0;        // wall time of the stream search
};

CompressedPart compress_part(const Mesh& part, const MeasuredSurface& measured, const PartOptions& options,
                             const std::string& source);

// CPU seconds of the calling thread (the fits' own time, whatever else runs).
double thread_cpu_seconds();

}  // namespace mm
