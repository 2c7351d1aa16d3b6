// Fuzz harness: the OBJ reader through io::read_mesh, as every command reads a mesh (tests/fuzz/fuzz_mesh.h).
#include <cstddef>
#include <cstdint>

#include "tests/fuzz/fuzz_mesh.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return gimforge::fuzz::fuzz_mesh_reader("input.obj", data, size);
}
