// CAD sample parts written by OpenCASCADE itself, so a clone without ../shared has STEP and
// IGES parts for the demo, the tests and the fuzz seeds. Deterministic: the same bytes on every
// run of one OpenCASCADE version (the files' time stamps are fixed).
#pragma once
#include <string>
#include <vector>

namespace mm::cad {

// "drilled_block": a 40 x 30 x 20 mm block with a 12 mm hole through it and a 6 mm hole
// through its side; "block_pair": two drilled blocks side by side, two solids in one file.
const std::vector<std::string>& sample_solid_names();

// The sample as a STEP (AP214) file, or an IGES (5.3, B-rep) file for format "iges"/"igs".
// std::invalid_argument for an unknown name or format.
std::string sample_solid_bytes(const std::string& name, const std::string& format);

}  // namespace mm::cad
