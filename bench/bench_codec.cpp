// Benchmark: encode + decode time of one image (issue #19 acceptance: a 513² image in ≤ 1 s). For a geometry
// image or spherical geometry image of an archive: the wavelet coder and JPEG 2000 at each byte budget, the
// encode with its rate control (the bisection on the quantization step, or OpenJPEG's rate allocation) and the
// decode, each the best of three runs; and the wavelet coder at the step the rate control found (one pass).
//
//   bench_codec ARCHIVE ITEM BYTES...    (ITEM gim/NAME or spherical/NAME)
#include <algorithm>
#include <chrono>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "io/archive.h"
#include "io/gim_archive.h"
#include "io/sphere_archive.h"
#include "kernels/codec/geometry_codec.h"
#include "kernels/codec/wavelet_coder.h"
#include "kernels/core/errors.h"

using namespace gimforge;

namespace {

template <class F>
double best_of_three(F&& f) {
  double best = 1e300;
  for (int i = 0; i < 3; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return best;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    fmt::print(stderr, "usage: bench_codec ARCHIVE ITEM BYTES...\n");
    return 2;
  }
  try {
    const io::Archive archive = io::Archive::open(argv[1]);
    const std::string item = argv[2];
    std::vector<Vec3> points;
    std::vector<std::uint8_t> mask;
    std::uint32_t width = 0, height = 0;
    LatticeExtension ext = LatticeExtension::Mirror;
    std::vector<float> xyz;
    if (item.starts_with("gim/")) {
      const GeometryImage g = io::read_geometry_image(archive, item.substr(4));
      xyz = g.positions;
      width = height = g.size;
    } else if (item.starts_with("spherical/")) {
      const SphericalImage s = io::read_spherical_image(archive, item.substr(10));
      xyz = s.positions;
      mask = s.mask;
      const DomainImage layout = s.layout();
      width = static_cast<std::uint32_t>(layout.width());
      height = static_cast<std::uint32_t>(layout.faces() * layout.height());
      ext = LatticeExtension::Sphere;
    } else {
      throw InvalidInput("ITEM is gim/NAME or spherical/NAME");
    }
    for (std::size_t k = 0; k < xyz.size() / 3; ++k) points.emplace_back(xyz[3 * k], xyz[3 * k + 1], xyz[3 * k + 2]);
    fmt::print("{} {} × {}\n{:>8} {:>8} {:>9} {:>9} {:>9} {:>9} {:>11}\n", item, width, height, "codec", "bytes", "PSNR dB",
               "encode s", "decode s", "total s", "1-pass enc");
    for (int a = 3; a < argc; ++a) {
      const std::size_t bytes = std::stoul(argv[a]);
      for (const GeometryCodec codec : {GeometryCodec::J2k, GeometryCodec::Wavelet}) {
        CodedGeometry coded;
        const double enc = best_of_three([&] {
          coded = encode_geometry(points, width, height, mask, codec, ext, CodingTarget{false, bytes, 0.0});
        });
        const double dec = best_of_three([&] {
          (void)decode_geometry(codec, coded.payload, coded.quantization, width, height, ext);
        });
        double one_pass = 0.0;
        if (codec == GeometryCodec::Wavelet) {
          const WaveletDecoded d = decode_wavelet(coded.payload);
          std::vector<Vec3> filled = points;
          fill_undefined(filled, width, height, mask);
          WaveletCodeOptions o;
          o.extension = ext;
          o.step = static_cast<double>(std::bit_cast<float>(std::uint32_t{coded.payload[12]} | std::uint32_t{coded.payload[13]} << 8 |
                                                            std::uint32_t{coded.payload[14]} << 16 | std::uint32_t{coded.payload[15]} << 24));
          one_pass = best_of_three([&] { (void)encode_wavelet(filled, width, mask, o); });
          (void)d;
        }
        fmt::print("{:>8} {:>8} {:>9.2f} {:>9.3f} {:>9.3f} {:>9.3f} {:>11}\n", codec_name(codec), coded.payload.size(), coded.psnr,
                   enc, dec, enc + dec, codec == GeometryCodec::Wavelet ? fmt::format("{:.3f}", one_pass) : std::string("-"));
      }
    }
  } catch (const Error& e) {
    fmt::print(stderr, "bench_codec: error: {}\n", e.what());
    return 1;
  }
  return 0;
}
