// Where the bytes of .mmc streams go: for each stream file, its sizes, whether re-encoding the
// decoded polyhedron reproduces it, and the ideal size of each section of the body, at the
// stream's bits and one bit finer. A development tool, not a test.
//
//   build/tests/codec/codec_report A.mmc [B.mmc ...]
#include <cstdio>
#include <cstdlib>
#include <iostream>

#include "codec/stream.h"
#include "codec/stream_v3.h"

namespace cd = mm::codec_detail;

int main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    try {
      const auto s = mm::read_stream_file(argv[i]);
      const mm::DecodedStream d = mm::decode(s, argv[i]);
      std::size_t quads = 0;
      for (const auto& f : d.mesh.faces) quads += f.size() == 4;
      std::printf("%s: version %d, %zu bytes, %d vertices, %zu faces (%zu quads), %zu creases, %zu corners, %d bits, %.2f bytes/vertex\n",
                  argv[i], d.version, s.size(), d.mesh.num_vertices(), d.mesh.faces.size(), quads,
                  d.mesh.creases.size(), d.mesh.corners.size(), d.quantization.bits,
                  static_cast<double>(s.size()) / std::max(1, d.mesh.num_vertices()));
      mm::CodecParams p;
      p.quant_bits = d.quantization.bits;
      p.metadata = d.metadata;
      std::printf("  re-encoding the decoded polyhedron gives %s bytes\n",
                  mm::encode(d.mesh, p) == s ? "the same" : "different");
      const mm::Quantization q = mm::quantization_for(d.mesh.points, p.quant_bits);
      cd::SectionBits sb;
      cd::encode_v3(d.mesh, q, mm::quantize(d.mesh.points, q), d.metadata, &sb);
      const mm::Quantization q1 = mm::quantization_for(d.mesh.points, p.quant_bits + 1);
      const auto finer = cd::encode_v3(d.mesh, q1, mm::quantize(d.mesh.points, q1), d.metadata);
      std::printf("  sections: header %zu, faces %.1f, coordinates %.1f (%.2f bits each), creases %.1f, corners %.1f, "
                  "metadata %.1f, checksum 4; at %d bits %zu bytes\n",
                  sb.header_bytes, sb.faces / 8, sb.coordinates / 8,
                  sb.coordinates / (3.0 * std::max(1, d.mesh.num_vertices())), sb.creases / 8, sb.corners / 8,
                  sb.metadata / 8, p.quant_bits + 1, finer.size());
      if (std::getenv("MM_REPORT_DUMP")) {  // grid, faces, creases, corners as text, for experiments
        FILE* f = std::fopen((std::string(argv[i]) + ".txt").c_str(), "w");
        std::fprintf(f, "%d %zu %zu %zu %d\n", d.mesh.num_vertices(), d.mesh.faces.size(), d.mesh.creases.size(), d.mesh.corners.size(), d.quantization.bits);
        for (int v = 0; v < d.mesh.num_vertices(); ++v) std::fprintf(f, "%d %d %d\n", d.grid(v, 0), d.grid(v, 1), d.grid(v, 2));
        for (const auto& fc : d.mesh.faces) { std::fprintf(f, "%zu", fc.size()); for (int x : fc) std::fprintf(f, " %d", x); std::fprintf(f, "\n"); }
        for (auto [a, b] : d.mesh.creases) std::fprintf(f, "%d %d\n", a, b);
        for (int c : d.mesh.corners) std::fprintf(f, "%d\n", c);
        std::fclose(f);
      }
    } catch (const std::exception& e) {
      std::cerr << e.what() << "\n";
      return 2;
    }
  }
  return 0;
}
