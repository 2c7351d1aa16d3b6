#include "jobs/proxy.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "jobs/scan_bricks.h"
#include "kernels/core/errors.h"
#include "kernels/mcgim/mcgim_image.h"
#include "kernels/scan/decimate.h"
#include "kernels/scan/surface_transfer.h"
#include "kernels/scan/wrap.h"

namespace gimforge::jobs {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::vector<Vec3> to_points(const std::vector<float>& xyz) {
  std::vector<Vec3> out(xyz.size() / 3);
  for (std::size_t i = 0; i < out.size(); ++i)
    out[i] = Vec3(static_cast<double>(xyz[3 * i]), static_cast<double>(xyz[3 * i + 1]), static_cast<double>(xyz[3 * i + 2]));
  return out;
}

void store(std::vector<float>& xyz, std::span<const Vec3> points) {
  for (std::size_t i = 0; i < points.size(); ++i)
    for (std::size_t c = 0; c < 3; ++c) xyz[3 * i + c] = static_cast<float>(points[i][static_cast<Eigen::Index>(c)]);
}

/// The full surface's colours at the transferred points (the proxy has none: the image gets them here);
/// undefined points get black.
void transfer_colors(const TriMesh& full, const TransferResult& t, std::vector<float>& colors) {
  if (!full.has_colors()) return;
  colors.assign(3 * t.faces.size(), 0.0f);
  for (std::size_t i = 0; i < t.faces.size(); ++i) {
    if (t.faces[i] == kNoFace) continue;
    const Face& f = full.faces[t.faces[i]];
    const Vec3 b = t.barycentric[i];
    const Vec3f c = static_cast<float>(b.x()) * full.colors[f[0]] + static_cast<float>(b.y()) * full.colors[f[1]] +
                    static_cast<float>(b.z()) * full.colors[f[2]];
    for (Eigen::Index k = 0; k < 3; ++k) colors[3 * i + static_cast<std::size_t>(k)] = c[k];
  }
}

/// An adaptively sampled image's positions at the m×m grid of its normal map: its samples lie at their
/// parameter points (sample_uv), not on the uniform grid, so each grid point takes the positions interpolated
/// linearly over the parameter-space triangle (two per pixel quad) that holds it, or, on an edge or in a
/// rounding gap, the one it is least outside of; one no triangle reaches (degenerate ones around it) keeps
/// its point in `uniform`.
std::vector<Vec3> adaptive_normal_grid_points(const GeometryImage& image, std::vector<Vec3> uniform) {
  const std::uint32_t n = image.size, m = image.normal_size;
  const auto index = [n](std::uint32_t i, std::uint32_t j) { return static_cast<std::size_t>(j) * n + i; };
  const auto uv = [&](std::size_t k) { return Vec2(image.sample_uv[2 * k], image.sample_uv[2 * k + 1]); };
  const auto position = [&](std::size_t k) {
    return Vec3(image.positions[3 * k], image.positions[3 * k + 1], image.positions[3 * k + 2]);
  };
  const auto cross = [](const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); };
  std::vector<Vec3> out = std::move(uniform);
  std::vector<double> outside(out.size(), std::numeric_limits<double>::infinity());
  const double step = 1.0 / (m - 1);
  const auto grid_range = [&](double lo, double hi) {  // grid indices within a cell of [lo, hi]
    const double a = std::clamp(std::floor(lo / step) - 1.0, 0.0, static_cast<double>(m - 1));
    const double b = std::clamp(std::ceil(hi / step) + 1.0, 0.0, static_cast<double>(m - 1));
    return std::array<std::uint32_t, 2>{static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b)};
  };
  const auto triangle = [&](std::size_t a, std::size_t b, std::size_t c) {
    const Vec2 A = uv(a), B = uv(b), C = uv(c);
    const double area = cross(B - A, C - A);
    if (!(std::abs(area) > 0.0)) return;
    const auto [x0, x1] = grid_range(std::min({A.x(), B.x(), C.x()}), std::max({A.x(), B.x(), C.x()}));
    const auto [y0, y1] = grid_range(std::min({A.y(), B.y(), C.y()}), std::max({A.y(), B.y(), C.y()}));
    for (std::uint32_t y = y0; y <= y1; ++y)
      for (std::uint32_t x = x0; x <= x1; ++x) {
        const Vec2 p(x * step, y * step);
        const double la = cross(B - p, C - p) / area, lb = cross(C - p, A - p) / area, lc = 1.0 - la - lb;
        const double by = -std::min({la, lb, lc});  // ≤ 0 inside
        const std::size_t k = static_cast<std::size_t>(y) * m + x;
        if (by >= outside[k]) continue;
        outside[k] = by;
        out[k] = la * position(a) + lb * position(b) + lc * position(c);
      }
  };
  for (std::uint32_t j = 0; j + 1 < n; ++j)
    for (std::uint32_t i = 0; i + 1 < n; ++i) {
      triangle(index(i, j), index(i + 1, j), index(i + 1, j + 1));
      triangle(index(i, j), index(i + 1, j + 1), index(i, j + 1));
    }
  return out;
}

/// The proxy geometry image interpolated at the m×m grid of its normal map (same [0,1]² square): bilinearly
/// between its pixels, or, sampled adaptively, at its samples' parameter points.
std::vector<Vec3> normal_grid_points(const GeometryImage& image) {
  const std::uint32_t n = image.size, m = image.normal_size;
  std::vector<Vec3> out(static_cast<std::size_t>(m) * m);
  auto at = [&](std::uint32_t i, std::uint32_t j) {
    const std::size_t k = 3 * (static_cast<std::size_t>(j) * n + i);
    return Vec3(image.positions[k], image.positions[k + 1], image.positions[k + 2]);
  };
  for (std::uint32_t j = 0; j < m; ++j)
    for (std::uint32_t i = 0; i < m; ++i) {
      const double x = static_cast<double>(i) / (m - 1) * (n - 1), y = static_cast<double>(j) / (m - 1) * (n - 1);
      const auto i0 = std::min(static_cast<std::uint32_t>(x), n - 2), j0 = std::min(static_cast<std::uint32_t>(y), n - 2);
      const double fx = x - i0, fy = y - j0;
      out[static_cast<std::size_t>(j) * m + i] = (1 - fx) * (1 - fy) * at(i0, j0) + fx * (1 - fy) * at(i0 + 1, j0) +
                                                 (1 - fx) * fy * at(i0, j0 + 1) + fx * fy * at(i0 + 1, j0 + 1);
    }
  if (image.sample_uv.size() == 2 * image.positions.size() / 3) return adaptive_normal_grid_points(image, std::move(out));
  return out;
}

}  // namespace

TriMesh make_proxy(const TriMesh& mesh, std::size_t faces, std::size_t brick_count, const ProgressCallback& progress,
                   std::map<std::string, double>& numbers) {
  const auto start = Clock::now();
  DecimateOptions options;
  options.target_faces = faces;
  options.progress = progress;
  // Bricks decimated in parallel first: the k-d bricks of the vertex histogram, as ranks cut a file
  // (jobs/scan_bricks.h), so one process and any number of ranks make the same proxy.
  const std::size_t bricks = std::min<std::size_t>(brick_count > 0 ? brick_count : proxy_bricks(mesh.num_faces(), faces), 64);
  // One brick too goes piece first (to twice the target) and then whole, as the ranks do.
  std::vector<std::uint8_t> brick_of_face(mesh.num_faces(), 0);
  if (bricks > 1) {
    CentroidHistogram histogram = brick_histogram(bounding_box(mesh));
    for (const Vec3& p : mesh.positions) histogram.add(p);
    const BrickPartition partition = partition_bricks(histogram, bricks);
    for (std::size_t f = 0; f < mesh.num_faces(); ++f)
      brick_of_face[f] = static_cast<std::uint8_t>(partition.brick_of(mesh.positions[mesh.faces[f][0]]));
  }
  options.brick_of_face = brick_of_face;
  DecimateResult proxy = decimate_quadric(mesh, options);
  if (proxy.mesh.faces.empty()) throw InvalidInput("the proxy has no face left");
  numbers["proxy_faces"] = static_cast<double>(proxy.mesh.num_faces());
  numbers["proxy_vertices"] = static_cast<double>(proxy.mesh.num_vertices());
  numbers["proxy_rejected_faces"] = static_cast<double>(proxy.rejected_faces);
  numbers["proxy_bricks"] = static_cast<double>(bricks);
  numbers["seconds_proxy"] = seconds_since(start);
  return std::move(proxy.mesh);
}

/// Above this share of the mesh's area away from the wrap, make_wrap_proxy warns (wrap_surface refuses 25 %).
constexpr double kWarnAreaLeftOut = 0.01;

TriMesh make_wrap_proxy(const TriMesh& mesh, std::uint32_t resolution, std::uint32_t closing, std::size_t faces,
                        std::size_t bricks, const std::string& source, const ProgressCallback& progress,
                        std::map<std::string, double>& numbers) {
  const auto start = Clock::now();
  const auto earlier = numbers.find("seconds_proxy");  // a decimation before the wrap (a huge input)
  const double seconds_before = earlier == numbers.end() ? 0.0 : earlier->second;
  WrapOptions options;
  options.resolution = resolution;
  options.closing = closing;
  options.progress = progress;
  WrapResult wrapped = wrap_surface(mesh, options);
  numbers["wrap_resolution"] = resolution;
  numbers["wrap_closing"] = closing;
  numbers["wrap_voxel"] = wrapped.voxel;
  numbers["wrap_faces"] = static_cast<double>(wrapped.mesh.num_faces());
  numbers["wrap_dropped_components"] = static_cast<double>(wrapped.dropped_components);
  numbers["wrap_dropped_faces"] = static_cast<double>(wrapped.dropped_faces);
  numbers["seconds_wrap"] = seconds_since(start);
  numbers["wrap_area_left_out"] = wrapped.area_left_out;
  if (wrapped.dropped_components > 0 && !source.empty())
    spdlog::warn("{}: the wrap keeps its largest piece; {} other piece(s) of {} faces ({:.1f} % of the wrap) are left "
                 "out: pieces more than about {} voxel(s) apart (a larger closing C in --wrap R:C joins pieces that "
                 "near; without --wrap, --method mcgim or relief keeps every piece)",
                 source, wrapped.dropped_components, wrapped.dropped_faces,
                 100.0 * static_cast<double>(wrapped.dropped_faces) /
                     static_cast<double>(wrapped.dropped_faces + wrapped.mesh.num_faces()),
                 2 * closing);
  if (wrapped.area_left_out > kWarnAreaLeftOut && !source.empty())
    spdlog::warn("{}: {:.1f} % of the mesh's area lies more than {} voxels from the wrap (pieces it left out, sealed "
                 "insides, sheets thinner than two voxels): the image does not represent it",
                 source, 100.0 * wrapped.area_left_out, kNearVoxels);
  if (wrapped.mesh.num_faces() <= faces) {  // already small enough: the wrap is the proxy
    numbers["proxy_faces"] = static_cast<double>(wrapped.mesh.num_faces());
    numbers["proxy_vertices"] = static_cast<double>(wrapped.mesh.num_vertices());
    numbers["proxy_rejected_faces"] = 0.0;
    numbers["proxy_bricks"] = 0.0;
    numbers["seconds_proxy"] = seconds_before;
    return std::move(wrapped.mesh);
  }
  TriMesh proxy = make_proxy(wrapped.mesh, faces, bricks, progress, numbers);
  numbers["seconds_proxy"] += seconds_before;
  return proxy;
}

void warn_proxy_rejections(const std::string& source, const std::map<std::string, double>& numbers) {
  if (const auto it = numbers.find("proxy_rejected_faces"); it != numbers.end() && it->second > 0.0)
    spdlog::warn("{}: the proxy left out {} faces its decimation could not insert (non-manifold fans)", source,
                 it->second);
}

std::vector<std::vector<Vec3>> transfer_point_sets(const Conversion& c) {
  std::vector<std::vector<Vec3>> sets;
  switch (c.method) {
    case Method::Gim: {
      const GeometryImage& image = c.gim.value().image;
      sets.push_back(to_points(image.positions));
      // The normal map's grid points, taken from the proxy image before it moves.
      if (image.normal_size > 1 && image.normals.size() == 3 * std::size_t{image.normal_size} * image.normal_size)
        sets.push_back(normal_grid_points(image));
      break;
    }
    case Method::Sphere: sets.push_back(to_points(c.sphere.value().image.positions)); break;
    case Method::Mcgim: sets.push_back(to_points(c.mcgim.value().image.positions)); break;
    case Method::Relief: throw InvalidInput("a relief map is not made from a proxy");
  }
  return sets;
}

void apply_transfers(Conversion& c, std::span<const TransferResult> results, const TriMesh* full) {
  if (results.empty()) throw InvalidInput("apply_transfers: no transfer results");
  const TransferResult& t = results[0];
  switch (c.method) {
    case Method::Gim: {
      GeometryImage& image = c.gim.value().image;
      store(image.positions, t.positions);
      if (full != nullptr && full->has_colors()) {
        transfer_colors(*full, t, image.colors);
        image.color_size = image.size;
      }
      if (results.size() > 1) store(image.normals, results[1].normals);
      break;
    }
    case Method::Sphere: {
      SphericalImage& image = c.sphere.value().image;
      store(image.positions, t.positions);
      if (full != nullptr) transfer_colors(*full, t, image.colors);
      break;
    }
    case Method::Mcgim: {
      McgimResult& r = c.mcgim.value();
      // Where the zipper made a quad's split decide the topology (pinned_quads), the split stays the one of
      // the zippered positions: chosen again from the moved ones it could leave a boundary loop or pinch off
      // a closed piece (the raw dragon through --wrap did both). The archive keeps the splits.
      if (r.image.zipper_diagonals.empty()) r.image.zipper_diagonals = zipper_diagonal_bits(r.image);
      store(r.image.positions, t.positions);
      // A multi-chart image's normals are central differences of its positions (docs/archive.md; preview and
      // decompress compute them so again), not the surface's normals at the moved samples.
      r.normals = multichart_normals(r.image);
      break;
    }
    case Method::Relief: throw InvalidInput("a relief map is not made from a proxy");
  }
  c.numbers["transfer_along_normal"] = static_cast<double>(t.stats.along_normal);
  c.numbers["transfer_closest"] = static_cast<double>(t.stats.closest);
  c.numbers["transfer_max_move"] = t.stats.max_move;
  c.numbers["transfer_rms_move"] = t.stats.rms_move;
}

void transfer_to_full_surface(const EmbreeDevice& device, const TriMesh& proxy, const TriMesh& full, Conversion& c,
                              const ProgressCallback& progress) {
  const auto start = Clock::now();
  TransferOptions options;
  options.progress = progress;
  const SurfaceTransfer transfer(device, proxy, full, options);
  std::vector<TransferResult> results;
  for (const std::vector<Vec3>& points : transfer_point_sets(c)) results.push_back(transfer(points));
  apply_transfers(c, results, &full);
  c.numbers["seconds_transfer"] = seconds_since(start);
}

}  // namespace gimforge::jobs
