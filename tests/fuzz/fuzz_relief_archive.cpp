// Fuzz harness: relief maps as `reconstruct`, `preview` and `render` read them: the bytes as an in-memory
// archive, the /relief listing, then read_relief_map (every array checked against the cells, layers and
// texture size) and read_relief_record for the first few names.
#include <cstddef>
#include <cstdint>

#include "io/relief_archive.h"
#include "tests/fuzz/fuzz_archive_image.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return gimforge::fuzz::expect_errors([&] {
    const gimforge::io::Archive archive = gimforge::fuzz::open_image(data, size);
    const auto names = gimforge::io::relief_map_names(archive);
    for (std::size_t i = 0; i < names.size() && i < 4; ++i) {
      gimforge::fuzz::expect_errors([&] {
        const gimforge::ReliefMap map = gimforge::io::read_relief_map(archive, names[i]);
        // What reconstruct_relief and the previews index: per-cell and per-layer arrays of matching sizes.
        const std::size_t layers = map.num_layers();
        if (map.external_faces.size() != map.cells.size() || map.first_layer.size() != map.cells.size() + 1 ||
            map.layer_cell.size() != layers || map.distances.size() != layers * map.texels_per_layer())
          __builtin_trap();
        for (const std::uint32_t g : map.layer_cell)
          if (g >= map.cells.size()) __builtin_trap();
      });
      gimforge::fuzz::expect_errors([&] { (void)gimforge::io::read_relief_record(archive, names[i]); });
    }
  });
}
