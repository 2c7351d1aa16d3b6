// Fuzz harness: consolidated batch archives as the tests and reports read them back:
// read_batch_summary (the /batch outputs, their datasets and per-item tables). The reader takes a path:
// the bytes go to a scratch file. The same bytes are also opened as an archive from memory.
#include <cstddef>
#include <cstdint>

#include "io/batch_archive.h"
#include "tests/fuzz/fuzz_archive_image.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = gimforge::fuzz::write_input("batch.h5", data, size);
  gimforge::fuzz::expect_errors([&] { (void)gimforge::io::read_batch_summary(path); });
  return gimforge::fuzz::expect_errors([&] { (void)gimforge::fuzz::open_image(data, size).info(); });
}
