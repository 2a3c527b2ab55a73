#include "samples/part_family.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mm::samples {

namespace {

// SplitMix64: a fixed, portable sequence for a seed (std distributions differ between libraries).
class Draw {
 public:
  explicit Draw(std::uint64_t seed) : s_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (s_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  int integer(int lo, int hi) { return lo + static_cast<int>(next() % static_cast<std::uint64_t>(hi - lo + 1)); }
  template <class T, std::size_t N>
  T pick(const T (&values)[N]) { return values[next() % N]; }
  bool coin() { return next() & 1; }

 private:
  std::uint64_t s_;
};

std::uint64_t family_seed(const std::string& name, std::uint64_t variant) {
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a of the name, then the variant
  for (unsigned char c : name) h = (h ^ c) * 1099511628211ull;
  return h ^ (variant * 0x9E3779B97F4A7C15ull);
}

}  // namespace

SamplePart sample_variant(const std::string& name, std::uint64_t variant) {
  if (variant == 0)
    for (auto& p : sample_parts())
      if (p.name == name) return p;
  Draw d(family_seed(name, variant));
  // Dimensions come from short lists of round values, as a designer's would: members share them.
  if (name == "plate_with_holes") {
    PlateWithHoles p;
    // Holes of 0.25-0.35 of the cell keep the rings between hole and cell square well shaped.
    const double cells[] = {15, 20, 25}, radii[] = {0.25, 0.3, 0.35}, thicknesses[] = {4, 6, 8};
    p.cells_x = d.integer(2, 6);
    p.cells_y = d.integer(1, 4);
    p.cell = d.pick(cells);
    p.hole_radius = d.pick(radii) * p.cell;
    p.thickness = d.pick(thicknesses);
    // Layers through the thickness no taller than three segments of a hole's rim.
    const double rim_segment = 2 * 3.14159265358979 * p.hole_radius / (4 * p.segments_per_side);
    p.layers = std::max(2, static_cast<int>(std::ceil(p.thickness / (3 * rim_segment))));
    p.holes.clear();
    for (int cy = 0; cy < p.cells_y; ++cy)
      for (int cx = 0; cx < p.cells_x; ++cx)
        if (d.coin()) p.holes.push_back({cx, cy});
    return {name, plate_with_holes(p)};
  }
  if (name == "chamfered_block") {
    ChamferedBlock p;
    const double sides[] = {20, 25, 30, 35, 40, 45, 50, 55, 60}, chamfers[] = {2, 3, 4};
    p.size_x = d.pick(sides);
    p.size_y = d.pick(sides);
    p.size_z = d.pick(sides) / 2;
    p.chamfer = d.pick(chamfers);
    return {name, chamfered_block(p)};
  }
  if (name == "flanged_cylinder") {
    FlangedCylinder p;
    const double bores[] = {5, 6, 8, 10, 12}, walls[] = {3, 4, 5, 6}, flanges[] = {6, 8, 10, 14},
                 heights[] = {20, 25, 30, 40};
    p.bore_radius = d.pick(bores);
    p.tube_radius = p.bore_radius + d.pick(walls);
    p.flange_radius = p.tube_radius + d.pick(flanges);
    p.height = d.pick(heights);
    p.flange_thickness = d.integer(4, 6);
    return {name, flanged_cylinder(p)};
  }
  throw std::invalid_argument("sample_variant: unknown part '" + name + "'");
}

}  // namespace mm::samples
