#include "kernels/sphere/sphere_adapt.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "kernels/core/closest_point.h"
#include "kernels/core/errors.h"
#include "kernels/sphere/octa_disk.h"

namespace gimforge {
namespace {

/// The sample every image sample copies: itself inside; on a side the one of the mated pair with the
/// smaller index along it (the smaller x or y, as flat_octahedron_glue evaluates); the first corner for all
/// four corners (the lower pole).
std::size_t canonical_sample(std::size_t k, std::uint32_t w) {
  const std::uint32_t last = w - 1;
  const auto i = static_cast<std::uint32_t>(k % w), j = static_cast<std::uint32_t>(k / w);
  const bool side_i = i == 0 || i == last, side_j = j == 0 || j == last;
  if (side_i && side_j) return 0;
  if (side_j) return std::size_t{j} * w + std::min(i, last - i);
  if (side_i) return std::size_t{std::min(j, last - j)} * w + i;
  return k;
}

}  // namespace

SphereAdaptResult adapt_flat_octahedron(const EmbreeDevice& device, const TriMesh& mesh, std::span<const Vec3> sphere,
                                        std::uint32_t n, AdaptStart start, AdaptOptions options, const RoiSource& roi) {
  if (n < 2) throw InvalidInput(fmt::format("adaptive sampling of a spherical image needs n >= 2 (n = {})", n));
  report_progress(options.progress, "cut", 0.0);
  const OctaDisk cut = cut_flat_octahedron(device, mesh, sphere);
  report_progress(options.progress, "cut", 1.0);
  const ParametrizedSurface surface(device, cut.disk, cut.uv);
  const std::uint32_t w = 2 * n + 1;
  const std::size_t count = std::size_t{w} * w;
  options.roi = nullptr;
  options.measure.glue = flat_octahedron_glue([&surface](const Vec2& p) { return surface.at(p).position; });
  // Every sample, the uniform start grid's included, is a point of the cut disk: a sample that switched
  // between the image's own point (I → D → S → M) and the disk's when it moves would jump by the
  // difference of the two parametrizations, and the moves' trials would measure that jump.
  const GridPositions positions_at = [&](const std::vector<Vec2>& grid) {
    std::vector<Vec3> out(count);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 1024), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t k = r.begin(); k != r.end(); ++k) {
        if (canonical_sample(k, w) != k) continue;
        out[k] = surface.at(grid[k]).position;
      }
    });
    for (std::size_t k = 0; k < count; ++k) out[k] = out[canonical_sample(k, w)];
    return out;
  };
  SphereAdaptResult result;
  result.disk_faces = cut.disk.faces.size();
  result.disk_flipped = cut.flipped;
  if (roi.kind == RoiSource::Kind::None) {
    result.sampling = sample_adaptively(device, cut.disk, cut.uv, w, start, positions_at, options);
  } else {
    std::vector<std::uint8_t> face_in;
    if (roi.kind == RoiSource::Kind::Vertices) {
      if (roi.vertices.size() != mesh.num_vertices())
        throw InvalidInput(fmt::format("region of interest: {} vertex flags for {} vertices", roi.vertices.size(),
                                       mesh.num_vertices()));
      face_in.reserve(cut.disk.faces.size());
      for (const std::uint32_t origin : cut.face_origin) {
        const Face& f = mesh.faces[origin];
        face_in.push_back(roi.vertices[f[0]] || roi.vertices[f[1]] || roi.vertices[f[2]] ? 1 : 0);
      }
    }
    // Mated side samples and the four corners are one surface point each: the mask's cells mirrored about
    // each side's midpoint, and the final flags, are glued, so the moves and the stored flags see them in the
    // ROI together.
    // (A mask's raster may have another size than the image: a picture's; the same fold applies.)
    const auto classes = [](std::uint32_t side) {
      std::vector<std::uint32_t> c(std::size_t{side} * side);
      for (std::size_t k = 0; k < c.size(); ++k) c[k] = static_cast<std::uint32_t>(canonical_sample(k, side));
      return c;
    };
    RoiMask mask = resolve_roi_mask(device, cut.disk, cut.uv, w, roi, face_in);
    glue_flags(mask.inside, classes(mask.size));
    RoiSampling r = sample_roi_adaptively(device, cut.disk, cut.uv, w, start, positions_at, mask, roi.enhance, options,
                                          classes(w));
    result.sampling.sample_uv = std::move(r.sample_uv);
    result.sampling.history = std::move(r.history);
    result.sampling.started_from_strips = r.started_from_strips;
    result.roi = std::move(r.summary);
  }
  result.sample_uv = result.sampling.sample_uv;
  result.positions = positions_at(result.sample_uv);
  if (mesh.has_colors()) {
    result.colors.resize(count);
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t c = canonical_sample(k, w);
      if (c != k) {
        result.colors[k] = result.colors[c];
        continue;
      }
      const ParametrizedSurface::Point p = surface.at(result.sample_uv[k]);
      const Face& f = mesh.faces[cut.face_origin[p.face]];
      const Vec3 b = closest_point_on_triangle(p.position, mesh.positions[f[0]], mesh.positions[f[1]], mesh.positions[f[2]]).barycentric;
      result.colors[k] = static_cast<float>(b[0]) * mesh.colors[f[0]] + static_cast<float>(b[1]) * mesh.colors[f[1]] +
                         static_cast<float>(b[2]) * mesh.colors[f[2]];
    }
  }
  return result;
}

}  // namespace gimforge
