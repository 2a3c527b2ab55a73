// The closest point of a triangle to a point, by Ericson's regions (Real-Time Collision
// Detection 5.1.5), as both closest-point trees compute it (the fit's BVH for its answer, the
// dense measurement's tree to decide which triangles CGAL measures). Inline: it is the inner
// loop of every query.
#pragma once

namespace mm {

// Barycentric weights (u, s, t) of a, b, c of the point of triangle a b c closest to p.
inline void closest_point_weights(const double* a, const double* b, const double* c, const double* p, double& u,
                                  double& s, double& t) {
  double ab[3], ac[3], ap[3], bp[3], cp[3];
  for (int k = 0; k < 3; ++k) {
    ab[k] = b[k] - a[k];
    ac[k] = c[k] - a[k];
    ap[k] = p[k] - a[k];
    bp[k] = p[k] - b[k];
    cp[k] = p[k] - c[k];
  }
  auto dot = [](const double* x, const double* y) { return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]; };
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  const double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
  if (d1 <= 0 && d2 <= 0) {
    u = 1, s = 0, t = 0;
  } else if (d3 >= 0 && d4 <= d3) {
    u = 0, s = 1, t = 0;
  } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    s = d1 / (d1 - d3), u = 1 - s, t = 0;
  } else if (d6 >= 0 && d5 <= d6) {
    u = 0, s = 0, t = 1;
  } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    t = d2 / (d2 - d6), u = 1 - t, s = 0;
  } else if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
    t = (d4 - d3) / ((d4 - d3) + (d5 - d6)), s = 1 - t, u = 0;
  } else {
    const double denom = 1.0 / (va + vb + vc);
    s = vb * denom, t = vc * denom, u = 1 - s - t;
  }
}

}  // namespace mm
