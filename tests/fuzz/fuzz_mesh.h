#pragma once
// The body of the four mesh-reader harnesses: the bytes in a scratch file named `file_name` (its extension
// picks the reader, the contents must confirm it), read through io::read_mesh as every command reads a mesh.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "io/mesh_io.h"
#include "tests/fuzz/fuzz_support.h"

namespace gimforge::fuzz {

inline int fuzz_mesh_reader(std::string_view file_name, const std::uint8_t* data, std::size_t size) {
  const auto path = write_input(file_name, data, size);
  return expect_errors([&] {
    io::ReadInfo info;
    const TriMesh mesh = io::read_mesh(path, &info);
    // What the reader promises (io/mesh_io.h): indices in range, finite coordinates; else a finding.
    for (const Face& f : mesh.faces)
      for (const std::uint32_t v : f)
        if (v >= mesh.num_vertices()) __builtin_trap();
    for (const Vec3& p : mesh.positions)
      if (!p.allFinite()) __builtin_trap();
  });
}

}  // namespace gimforge::fuzz
