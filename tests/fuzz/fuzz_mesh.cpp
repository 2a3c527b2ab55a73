// Mesh readers (STL, OBJ, OFF, PLY, 3MF, GLB, glTF) on hostile bytes: the first byte picks the format. A reader
// may refuse with InputError; anything else (a crash, another exception, a sanitizer report,
// an allocation past libFuzzer's limit) is a finding.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "meshio/read_mesh.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const char* formats[] = {"stl", "obj", "off", "ply", "3mf", "glb", "gltf"};
  const std::string_view bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  try {
    mm::parse_mesh(bytes, formats[data[0] % 7], "fuzz");
  } catch (const mm::InputError&) {
  }
  return 0;
}
