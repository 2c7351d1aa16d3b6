// Benchmark: ROI JPEG 2000 of an adaptive geometry image (issue #18 item 5; adaptive geometry images §4,
// Fig. 11, Table 2). For an item converted with --roi (its roi_mask), at each rate: the image coded within
// the same bytes plainly (one JPEG 2000 codestream) and with the ROI first (kernels/codec/j2k.h
// encode_roi_priority), decoded, and the directed Hausdorff distance from the ROI's reconstruction to the
// input (15 points on every triangle of the quads whose four samples are in the ROI, exact closest points)
// and the whole image's PSNR (`gimforge metrics`' measure) of both.
//
//   bench_roi_j2k ARCHIVE NAME MESH RATE...   (RATE in bits per pixel of the n × n image, e.g. 0.5 1 2)
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "io/archive.h"
#include "io/gim_archive.h"
#include "jobs/load_mesh.h"
#include "jobs/pipeline.h"
#include "kernels/codec/j2k.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/core/hausdorff.h"
#include "kernels/gim/geometry_image.h"

using namespace gimforge;

namespace {

struct RoiError {
  double max{0.0};
  double rms{0.0};
};

/// Directed distance from the ROI's quads of the image to the input.
RoiError roi_error(const TriangleBvh& input, std::span<const float> xyz, std::uint32_t n, std::span<const std::uint8_t> roi) {
  const auto at = [&](std::uint32_t i, std::uint32_t j) {
    const std::size_t p = std::size_t{j} * n + i;
    return Vec3(xyz[3 * p], xyz[3 * p + 1], xyz[3 * p + 2]);
  };
  RoiError e;
  double weighted = 0.0, area = 0.0;
  for (std::uint32_t j = 0; j + 1 < n; ++j)
    for (std::uint32_t i = 0; i + 1 < n; ++i) {
      if (!roi[j * n + i] || !roi[j * n + i + 1] || !roi[(j + 1) * n + i] || !roi[(j + 1) * n + i + 1]) continue;
      const Vec3 a = at(i, j), b = at(i + 1, j), c = at(i + 1, j + 1), d = at(i, j + 1);
      // The shorter diagonal, as reconstruct_geometry_image splits a quad.
      const bool ac = (c - a).squaredNorm() <= (d - b).squaredNorm();
      const std::array<std::array<Vec3, 3>, 2> tris = ac ? std::array<std::array<Vec3, 3>, 2>{{{a, b, c}, {a, c, d}}}
                                                         : std::array<std::array<Vec3, 3>, 2>{{{a, b, d}, {b, c, d}}};
      for (const auto& t : tris) {
        const double tri_area = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).norm();
        double sum = 0.0;
        int count = 0;
        for (int u = 0; u <= 4; ++u)
          for (int v = 0; u + v <= 4; ++v) {
            const Vec3 p = t[0] + (u / 4.0) * (t[1] - t[0]) + (v / 4.0) * (t[2] - t[0]);
            const double dist = input.closest_point(p).distance;
            e.max = std::max(e.max, dist);
            sum += dist * dist;
            ++count;
          }
        weighted += tri_area * sum / count;
        area += tri_area;
      }
    }
  e.rms = area > 0.0 ? std::sqrt(weighted / area) : 0.0;
  return e;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 5) {
    std::fputs("usage: bench_roi_j2k ARCHIVE NAME MESH RATE...  (RATE: bits per pixel)\n", stderr);
    return 2;
  }
  try {
    const std::string archive_path = argv[1], name = argv[2];
    const io::Archive archive = io::Archive::open(archive_path);
    const GeometryImage image = io::read_geometry_image(archive, name);
    const std::uint32_t n = image.size;
    const std::vector<std::uint8_t> roi = archive.root().open_group("gim/" + name).open_dataset("roi_mask").read<std::uint8_t>();
    if (roi.size() != std::size_t{n} * n) throw FormatError("roi_mask does not match the image");
    TriMesh mesh = jobs::load_mesh(argv[3], {.repair = true, .require_manifold = false, .require_oriented = false, .warn = false, .topology = false}).mesh;
    jobs::to_local_frame(mesh, jobs::item_origin(archive, jobs::Method::Gim, name));
    const EmbreeDevice device;
    const TriangleBvh input(device, mesh);
    const auto psnr = [&](std::span<const float> xyz) {
      const TriMesh recon = reconstruct_geometry_image(xyz, n, &image.sideband);
      return symmetric_hausdorff(device, mesh, recon, {200000}).psnr;
    };
    Quantization q;
    const Planes16 planes = quantize_positions(image.positions, n, n, q);
    const RoiError full = roi_error(input, image.positions, n, roi);
    fmt::print("{} n = {}: ROI {} of {} samples; float image: ROI→input max {:.4g} rms {:.4g}, PSNR {:.2f} dB\n", name, n,
               std::count(roi.begin(), roi.end(), 1), roi.size(), full.max, full.rms, psnr(image.positions));
    fmt::print("| rate bpp | budget B | plain B | ROI-first B (header + window + image) | ROI→input max plain | ROI-first | ratio | rms plain | ROI-first | rms ratio | PSNR plain | ROI-first |\n");
    fmt::print("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (int k = 4; k < argc; ++k) {
      const double rate = std::stod(argv[k]);
      const auto budget = static_cast<std::size_t>(rate * n * n / 8.0);
      const std::vector<std::uint8_t> plain = encode_j2k(planes, {budget, false});
      const std::vector<float> plain_xyz = dequantize_positions(decode_j2k(plain), q);
      // The payload's header (the window's place and size, the codestreams' split) counts against the budget.
      const RoiCoded coded = encode_roi_priority(planes, roi, budget - std::min(budget, kRoiPayloadHeader));
      const std::vector<float> roi_xyz = dequantize_positions(decode_roi_priority(coded), q);
      const RoiError a = roi_error(input, plain_xyz, n, roi), b = roi_error(input, roi_xyz, n, roi);
      const std::string form = fmt::format("{} + {} + {}{}", kRoiPayloadHeader, coded.window.size(), coded.background.size() - coded.shared_header,
                                           coded.shared_header != 0 ? ", header shared" : "");
      fmt::print("| {} | {} | {} | {} ({}) | {:.4g} | {:.4g} | {:.2f} | {:.4g} | {:.4g} | {:.2f} | {:.2f} | {:.2f} |\n", rate, budget,
                 plain.size(), kRoiPayloadHeader + coded.bytes(), form, a.max, b.max, b.max / a.max, a.rms, b.rms, b.rms / a.rms, psnr(plain_xyz),
                 psnr(roi_xyz));
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "bench_roi_j2k: %s\n", e.what());
    return 1;
  }
  return 0;
}
