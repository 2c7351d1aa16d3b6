// Fuzz harness: batch shards as `gimforge batch` reads them back (on --resume, and when it consolidates
// the archive): read_shard_info (structure, relief representation checked), read_shard (pixel data and
// mask), copy_representation into an in-memory file. The readers take a path: the bytes go to a
// scratch file.
#include <hdf5.h>

#include <cstddef>
#include <cstdint>

#include "io/batch_shard.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = gimforge::fuzz::write_input("shard.h5", data, size);
  return gimforge::fuzz::expect_errors([&] {
    const gimforge::io::ShardInfo info = gimforge::io::read_shard_info(path);
    if (info.has_representation) {
      gimforge::h5::FileAccess memory;
      memory.add("core driver", [](gimforge::h5::Hid plist) { return H5Pset_fapl_core(plist, 1 << 16, 0); });
      gimforge::h5::File out = gimforge::h5::File::create(gimforge::fuzz::scratch_dir() / "copy.h5",
                                                          gimforge::h5::CreateMode::kTruncate, memory);
      gimforge::io::copy_representation(path, out, "item");
      return;
    }
    const gimforge::io::Shard shard = gimforge::io::read_shard(path);
    const std::size_t pixels = std::size_t{info.height} * info.width;
    if (shard.arrays.data.size() != info.channels * pixels) __builtin_trap();
    if (!shard.arrays.mask.empty() && shard.arrays.mask.size() != pixels) __builtin_trap();
  });
}
