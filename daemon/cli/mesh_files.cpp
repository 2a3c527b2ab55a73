#include "cli/mesh_files.h"

#include <cctype>
#include <string_view>

#include "cli/file_util.h"
#include "cad/read_part.h"
#include "codec/stream.h"
#include "meshio/read_mesh.h"

namespace mm::cli {

bool is_stream_path(const std::string& path) { return lower_extension(path) == "mmc"; }

bool is_triangle_path(const std::string& path) { return stores_triangles_only(lower_extension(path)); }

bool is_mesh_path(const std::string& path) {
  return is_mesh_format(lower_extension(path));
}

bool is_part_path(const std::string& path) { return is_part_format(lower_extension(path)); }

InputFile load_input(const std::string& path) {
  if (!is_stream_path(path) && !is_part_path(path))
    throw InputError(path, "unknown file type (expected " + part_format_list() + ", or .mmc)");
  InputFile in;
  const std::vector<std::uint8_t> bytes = read_file_bytes(path);
  in.sha256 = sha256_hex(bytes.data(), bytes.size());
  if (is_stream_path(path)) {
    DecodedStream s = decode(bytes, path);
    in.mesh = std::move(s.mesh);
    in.stream = true;
    in.quant_bits = s.quantization.bits;
    in.metadata = std::move(s.metadata);
  } else {
    const std::string_view view(reinterpret_cast<const char*>(bytes.data()), bytes.size());
    in.mesh = parse_part(view, lower_extension(path), path);
  }
  return in;
}

void write_output(const Mesh& mesh, const std::string& path, int quant_bits,
                  const std::map<std::string, std::string>& metadata) {
  if (is_stream_path(path)) {
    CodecParams params;
    params.quant_bits = quant_bits;
    params.metadata = metadata;
    std::vector<std::uint8_t> bytes;
    try {
      bytes = encode(mesh, params);
    } catch (const InputError& e) {
      throw InputError(path, "cannot encode as a stream: " + e.reason());
    }
    write_stream_file(path, bytes);
  } else if (is_mesh_path(path)) {
    write_mesh(mesh, path);
  } else {
    throw InputError(path, "unknown output type (expected " + mesh_format_list() + ", or .mmc)");
  }
}

}  // namespace mm::cli
