// Fuzz harness: consolidated batch archives as the tests and reports read them back:
// read_batch_summary (the /batch outputs, their datasets and per-item tables), and every item stacked in a
// geometry-image or spherical-image output read back as reconstruct and preview read it (io/batch_items.h).
// The summary reader takes a path: the bytes go to a scratch file. The same bytes are also opened as an
// archive from memory.
#include <cstddef>
#include <cstdint>

#include "io/batch_archive.h"
#include "io/batch_items.h"
#include "tests/fuzz/fuzz_archive_image.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = gimforge::fuzz::write_input("batch.h5", data, size);
  gimforge::fuzz::expect_errors([&] { (void)gimforge::io::read_batch_summary(path); });
  gimforge::fuzz::expect_errors([&] {
    const gimforge::io::Archive archive = gimforge::fuzz::open_image(data, size);
    for (const gimforge::io::BatchItem& item : gimforge::io::batch_items(archive)) {
      if (item.group) continue;  // items/<k>: the group readers' own harnesses
      gimforge::fuzz::expect_errors([&] { (void)gimforge::io::read_batch_item_origin(archive, item, 1e12); });
      if (item.method == "gim")
        gimforge::fuzz::expect_errors([&] { (void)gimforge::io::read_batch_geometry_image(archive, item); });
      else if (item.method == "sphere")
        gimforge::fuzz::expect_errors([&] { (void)gimforge::io::read_batch_spherical_image(archive, item); });
    }
  });
  return gimforge::fuzz::expect_errors([&] { (void)gimforge::fuzz::open_image(data, size).info(); });
}
