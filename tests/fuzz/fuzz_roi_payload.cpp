// Fuzz harness: a ROI-first JPEG 2000 payload (codec "j2k-roi", kernels/codec/j2k.h) as readers meet it once
// its archive's CRC-32 matched, for a 65 × 65 image of three planes: roi_payload_window (the window fusing
// trusts), then decode_roi_payload. The header checks, the shared main header's rebuilding and OpenJPEG's
// decoding, without the checksum that keeps archive mutations away from them.
#include <cstddef>
#include <cstdint>
#include <span>

#include "kernels/codec/j2k.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  constexpr std::uint32_t n = 65;
  const std::span<const std::uint8_t> payload(data, size);
  return gimforge::fuzz::expect_errors([&] {
    const std::vector<std::uint8_t> window = gimforge::roi_payload_window(payload, n, n);
    if (!window.empty() && window.size() != std::size_t{n} * n) __builtin_trap();
    const gimforge::Planes16 image = gimforge::decode_roi_payload(payload, n, n, 3);
    if (image.width != n || image.height != n || image.components != 3 || image.samples.size() != 3 * std::size_t{n} * n)
      __builtin_trap();
  });
}
