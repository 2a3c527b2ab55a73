// Grid values for a control polyhedron chosen for its subdivided surface, not value by value.
// Rounding each coordinate to its nearest grid value adds errors that the subdivision averages
// into the surface; moving a few values a cell the other way cancels part of that. On a coarse
// grid this can keep a smaller polyhedron within the tolerance (abc8 at seed 2: 448 bytes at
// 8 bits descended, against 471 for the smallest stream of nearest values).
#pragma once
#include "meshio/mesh.h"

namespace mm {

// `control` with its points moved to grid positions of encode()'s grid at `bits`: starting from
// the nearest grid values, each coordinate moves one cell at a time (sweeps over the vertices in
// order, per axis, until none moves) while that brings the refined vertices after `levels`
// subdivision steps closer, in the least-squares sense, to those of `control` itself. Values at
// an axis's minimum or maximum stay and nothing moves onto or beyond them, so encode() at `bits`
// finds the same grid and codes the returned points exactly. A least-squares choice: it may
// raise the largest distance to the part, so the caller measures. Deterministic. Throws as
// subdivision_operator and quantization_for do.
Mesh descended_on_grid(const Mesh& control, int bits, int levels);

}  // namespace mm
