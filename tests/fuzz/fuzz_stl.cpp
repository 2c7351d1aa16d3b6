// Fuzz harness: the STL reader through io::read_mesh, as every command reads a mesh (the bytes in a
// scratch file named *.stl, so the extension picks the reader and the contents must confirm it).
#include <cstddef>
#include <cstdint>

#include "io/mesh_io.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = gimforge::fuzz::write_input("input.stl", data, size);
  return gimforge::fuzz::expect_errors([&] {
    gimforge::io::ReadInfo info;
    const gimforge::TriMesh mesh = gimforge::io::read_mesh(path, &info);
    // What the reader promises (io/mesh_io.h): indices in range, finite coordinates; else a finding.
    for (const gimforge::Face& f : mesh.faces)
      for (const std::uint32_t v : f)
        if (v >= mesh.num_vertices()) __builtin_trap();
    for (const gimforge::Vec3& p : mesh.positions)
      if (!p.allFinite()) __builtin_trap();
  });
}
