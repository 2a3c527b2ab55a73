// Where the bytes of .mmc streams go: for each stream file, the header, checksum and payload
// sections of the stored stream, and the size of the same polyhedron re-encoded in each
// written format version. A development tool (docs/compression.md quotes its output), not a test.
//
//   build/tests/codec/codec_report A.mmc [B.mmc ...]
#include <zstd.h>

#include <cstdio>
#include <cstdlib>
#include <iostream>

#include "codec/bytes.h"
#include "codec/stream.h"
#include "codec/stream_detail.h"
#include "codec/stream_v3.h"

namespace cd = mm::codec_detail;

namespace {

std::size_t zstd_size(const std::uint8_t* p, std::size_t n) {
  std::vector<std::uint8_t> out(ZSTD_compressBound(n));
  return ZSTD_compress(out.data(), out.size(), p, n, 19);
}

// Version 1/2 payload sections: raw bytes and zstd-compressed alone.
void report_v2(const std::vector<std::uint8_t>& s, const mm::DecodedStream& d) {
  const cd::Parts parts = cd::split(s.data(), s.size(), "report");
  const auto& raw = parts.raw;
  cd::Reader in(raw.data(), raw.size(), "report", "payload");
  std::size_t sizes[3];
  for (auto& z : sizes) z = in.varint("size", raw.size());
  const char* names[] = {"face symbols", "face ranks", "face indices"};
  std::size_t header_bytes = s.size() - 4 - (s.size() - 4);  // filled below
  (void)header_bytes;
  std::printf("  %-16s %6s %6s\n", "section", "raw", "zstd");
  for (int k = 0; k < 3; ++k) {
    const std::uint8_t* p = in.bytes(sizes[k], names[k]);
    std::printf("  %-16s %6zu %6zu\n", names[k], sizes[k], zstd_size(p, sizes[k]));
  }
  const auto edges = mm::unique_edges(d.mesh);
  const std::size_t cb = (edges.size() + 7) / 8;
  const std::uint8_t* p = in.bytes(cb, "creases");
  std::printf("  %-16s %6zu %6zu  (%zu edges, %zu creases)\n", "crease bits", cb, zstd_size(p, cb),
              edges.size(), d.mesh.creases.size());
  const std::uint8_t* c0 = in.position();
  for (std::size_t c = 0; c < d.mesh.corners.size(); ++c) in.varint("corner", ~0ull);
  const std::size_t corner_bytes = static_cast<std::size_t>(in.position() - c0);
  std::printf("  %-16s %6zu %6zu  (%zu corners)\n", "corner gaps", corner_bytes, zstd_size(c0, corner_bytes),
              d.mesh.corners.size());
  in.bytes(3, "k");
  const std::size_t bits = in.varint("bits", raw.size());
  const std::uint8_t* b = in.bytes(bits, "coords");
  std::printf("  %-16s %6zu %6zu  (%.2f bits per coordinate)\n", "coordinates", bits + 4, zstd_size(b, bits),
              8.0 * bits / (3.0 * d.mesh.num_vertices()));
  std::printf("  %-16s %6zu\n", "metadata", in.remaining());
  const std::size_t payload_stored = s.size() - 4 - (s.size() - 4 - 0);
  (void)payload_stored;
  std::printf("  payload %zu raw -> stored %s; header+crc %zu\n", raw.size(),
              (parts.header.flags & cd::kFlagZstd) ? "zstd" : "as is",
              s.size() - ((parts.header.flags & cd::kFlagZstd) ? zstd_size(raw.data(), raw.size()) : raw.size()));
}

}  // namespace

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
      if (d.version <= 2) report_v2(s, d);
      {
        mm::CodecParams p;
        p.quant_bits = d.quantization.bits;
        p.metadata = d.metadata;
        p.format_version = d.version >= 3 ? 3 : 2;
        std::printf("  re-encoding the decoded polyhedron as version %d gives %s bytes\n", p.format_version,
                    d.version >= 2 && mm::encode(d.mesh, p) == s ? "the same" : "different");
      }
      {
        // The same polyhedron (decoded points re-quantise to the same grid) in each version.
        mm::CodecParams p;
        p.quant_bits = d.quantization.bits;
        p.metadata = d.metadata;
        p.format_version = 2;
        const std::size_t v2 = mm::encode(d.mesh, p).size();
        // Version 3 needs its own grid (power-of-two cells): the positions move by < 1 step.
        const mm::Quantization q = mm::quantization_for(d.mesh.points, p.quant_bits);
        cd::SectionBits sb;
        const auto v3 = cd::encode_v3(d.mesh, q, mm::quantize(d.mesh.points, q), d.metadata, &sb);
        // And one bit finer, whose step is at most version 2's (the cell grid's step at B bits is
        // 1 to 2 times the bounding-box grid's).
        const mm::Quantization q1 = mm::quantization_for(d.mesh.points, p.quant_bits + 1);
        const auto v3_finer = cd::encode_v3(d.mesh, q1, mm::quantize(d.mesh.points, q1), d.metadata);
        std::printf("  version 2: %zu bytes (step %.4g); version 3: %zu bytes (%.1f%%, step %.4g), at %d bits %zu (%.1f%%, step %.4g)\n"
                    "  version 3 sections: header %zu, faces %.1f, coordinates %.1f (%.2f bits each), creases %.1f, corners %.1f, metadata %.1f, checksum 4\n",
                    v2, d.quantization.step, v3.size(), 100.0 * v3.size() / v2, q.step, p.quant_bits + 1,
                    v3_finer.size(), 100.0 * v3_finer.size() / v2, q1.step, sb.header_bytes, sb.faces / 8, sb.coordinates / 8,
                    sb.coordinates / (3.0 * std::max(1, d.mesh.num_vertices())), sb.creases / 8, sb.corners / 8, sb.metadata / 8);
      }
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
