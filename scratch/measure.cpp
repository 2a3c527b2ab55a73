#include <iostream>
#include <random>
#include "jobs/detect.h"
#include "jobs/protect.h"
#include "meshio/read_mesh.h"
#include "subdivision/subdivide.h"
using namespace mm; using namespace mm::jobs;
Mesh with_noise(Mesh m, double amplitude, unsigned seed) {
  double side = (m.points.colwise().maxCoeff() - m.points.colwise().minCoeff()).maxCoeff();
  std::mt19937 g(seed); std::uniform_real_distribution<double> u(-amplitude * side, amplitude * side);
  for (Eigen::Index i = 0; i < m.points.rows(); ++i) for (int k = 0; k < 3; ++k) m.points(i, k) += u(g);
  return m;
}
int main(int, char** argv) {
  PreparedAsset a = prepare_asset(read_mesh(argv[1]), {}, "x");
  CopyCandidate cc; cc.copy_id = 1; for (int i = 0; i < 32; ++i) cc.key[i] = i * 7 + 1; for (int i = 0; i < 24; ++i) cc.nonce[i] = i; cc.payload = 0x4377;
  Mesh c = make_copy(a, cc.key, cc.nonce, cc.payload, cc.settings);
  ResyncContext ctx = make_resync_context(a);
  CopyFiles f = make_copy_files(a, c, {}, false);
  write_mesh(f.decoded, "/tmp/x.stl");
  Mesh stl = read_mesh("/tmp/x.stl");
  for (auto [name, m] : std::vector<std::pair<std::string, Mesh>>{{"stl", stl}, {"stl+noise", with_noise(stl, 5e-4, 3)}, {"sub1", subdivide(f.decoded, 1)}}) {
    auto r0 = resynchronize(ctx, m);
    auto r1 = resynchronize_suspect(ctx, m);
    std::cout << name << ": plain " << r0.method << " res " << r0.residual_rms << " -log10p " << detect_copy(a, r0.points, {cc}, 1e-6).best.neg_log10_p
              << " | refined res " << r1.residual_rms << " -log10p " << detect_copy(a, r1.points, {cc}, 1e-6).best.neg_log10_p << "\n";
  }
}
