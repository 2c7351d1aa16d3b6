// Fuzz harness: geometry images as `reconstruct` and `preview` read them: the bytes as an in-memory
// archive (Archive::open's identity checks), the /gim listing, then read_geometry_image (with its checks
// of shapes, sideband and attributes), its region of interest, and read_gim_record for the first few names.
#include <cstddef>
#include <cstdint>

#include "io/gim_archive.h"
#include "tests/fuzz/fuzz_archive_image.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return gimforge::fuzz::expect_errors([&] {
    const gimforge::io::Archive archive = gimforge::fuzz::open_image(data, size);
    (void)archive.info();
    const auto names = gimforge::io::geometry_image_names(archive);
    for (std::size_t i = 0; i < names.size() && i < 4; ++i) {
      gimforge::fuzz::expect_errors([&] {
        const gimforge::GeometryImage image = gimforge::io::read_geometry_image(archive, names[i]);
        // What preview indexes: size² positions (and normal_size² normals).
        if (image.positions.size() != std::size_t{3} * image.size * image.size) __builtin_trap();
        if (image.normals.size() != std::size_t{3} * image.normal_size * image.normal_size) __builtin_trap();
        gimforge::fuzz::check_roi_mask(archive, gimforge::io::kGeometryImages, names[i], image.size);
      });
      gimforge::fuzz::expect_errors([&] { (void)gimforge::io::read_gim_record(archive, names[i]); });
    }
  });
}
