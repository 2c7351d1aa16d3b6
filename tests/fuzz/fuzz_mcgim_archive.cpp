// Fuzz harness: multi-chart geometry images as `reconstruct` and `preview` read them: the bytes as an
// in-memory archive, the /mcgim listing, then read_multichart_image (attributes bounded before any
// allocation, shapes, dtypes, chart ids, zipper rows, finite/NaN samples, clusters at one position) and
// read_multichart_extras for the first few names, and the §3 reconstruction of what was read.
#include <cstddef>
#include <cstdint>

#include "io/mcgim_archive.h"
#include "tests/fuzz/fuzz_archive_image.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return gimforge::fuzz::expect_errors([&] {
    const gimforge::io::Archive archive = gimforge::fuzz::open_image(data, size);
    const auto names = gimforge::io::multichart_image_names(archive);
    for (std::size_t i = 0; i < names.size() && i < 4; ++i) {
      gimforge::fuzz::expect_errors([&] {
        const gimforge::MultiChartImage image = gimforge::io::read_multichart_image(archive, names[i]);
        // What reconstruct indexes: three coordinates, one mask, chart and cluster entry per sample.
        const std::size_t n = image.samples();
        if (image.positions.size() != 3 * n || image.mask.size() != n || image.unified.size() != n) __builtin_trap();
        const gimforge::TriMesh mesh = gimforge::reconstruct_multichart(image);
        for (const gimforge::Face& f : mesh.faces)
          for (std::uint32_t v : f)
            if (v >= mesh.positions.size()) __builtin_trap();
      });
      gimforge::fuzz::expect_errors([&] {
        const gimforge::io::McgimExtras extras = gimforge::io::read_multichart_extras(archive, names[i]);
        (void)extras;
      });
    }
  });
}
