// Fuzz harness: spherical geometry images as `reconstruct`, `preview` and `convert --method sphere` (the
// stored parametrization) read them: the bytes as an in-memory archive, the /spherical listing, then
// read_spherical_image (shapes, mask against positions, domain), read_spherical_record and
// read_sphere_parametrization for the first few names, and the region of interest of a flat-octa image.
#include <cstddef>
#include <cstdint>

#include "io/sphere_archive.h"
#include "tests/fuzz/fuzz_archive_image.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return gimforge::fuzz::expect_errors([&] {
    const gimforge::io::Archive archive = gimforge::fuzz::open_image(data, size);
    const auto names = gimforge::io::spherical_image_names(archive);
    for (std::size_t i = 0; i < names.size() && i < 4; ++i) {
      gimforge::fuzz::expect_errors([&] {
        const gimforge::SphericalImage image = gimforge::io::read_spherical_image(archive, names[i]);
        // What preview and reconstruct index: one mask entry and three coordinates per sample of the layout.
        const std::size_t samples = image.layout().num_samples();
        if (image.mask.size() != samples || image.positions.size() != 3 * samples) __builtin_trap();
        if (!image.colors.empty() && image.colors.size() != 3 * samples) __builtin_trap();
        // Adaptive sampling (flat-octa): two parameter coordinates per sample, in the square.
        if (!image.sample_uv.empty() && image.sample_uv.size() != 2 * samples) __builtin_trap();
        for (const float v : image.sample_uv)
          if (!(v >= 0.0f && v <= 1.0f)) __builtin_trap();
        // The region of interest (preview's <name>_roi.png): flags 0 or 1, one per sample of the square.
        if (image.layout().faces() == 1 && image.layout().width() == image.layout().height())
          gimforge::fuzz::check_roi_mask(archive, gimforge::io::kSphericalImages, names[i],
                                         static_cast<std::uint64_t>(image.layout().width()));
      });
      gimforge::fuzz::expect_errors([&] { (void)gimforge::io::read_spherical_record(archive, names[i]); });
      gimforge::fuzz::expect_errors([&] {
        const auto p = gimforge::io::read_sphere_parametrization(archive, names[i]);
        if (p.sphere.size() < p.input_vertices) __builtin_trap();
      });
    }
  });
}
