#include "jobs/brick_relief.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstring>
#include <limits>
#include <optional>
#include <span>
#include <fstream>
#include <sys/resource.h>
#include <unistd.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/parallel_sort.h>

#include "io/input_file.h"
#include "io/ply_ranges.h"
#include "jobs/brick_metrics.h"
#include "jobs/error_naming.h"
#include "jobs/scan_bricks.h"
#include "kernels/core/errors.h"
#include "kernels/relief/relief_cells.h"
#include "kernels/relief/relief_fidelity.h"
#include "kernels/relief/relief_map.h"
#include "mpi/agree.h"

namespace gimforge::jobs {
namespace {

using Clock = std::chrono::steady_clock;
constexpr int kHitsTag = 75;
/// Bytes per message of the hit and texel transfers (MPI counts are int).
constexpr std::size_t kChunkBytes = std::size_t{1} << 28;
/// Scan vertices measured per batch in the fidelity's maximum.
constexpr std::size_t kVertexBatch = std::size_t{1} << 20;

double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// This process's resident memory now, in MB (for the -v log of each phase); 0 when /proc is unreadable.
double resident_mb() {
  std::ifstream statm("/proc/self/statm");
  double pages = 0.0, resident = 0.0;
  statm >> pages >> resident;
  return resident * static_cast<double>(::sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0);
}

/// Whether every edge of this rank's own faces lies on exactly two faces, counted over the own and ghost
/// faces (which hold every face around an own face's edge): is_closed_edge_manifold restricted to the
/// edges this rank owns.
bool own_edges_closed(const BrickMesh& brick) {
  const auto key = [](std::uint32_t a, std::uint32_t b) {
    return (static_cast<std::uint64_t>(std::min(a, b)) << 32) | std::max(a, b);
  };
  std::vector<std::uint64_t> edges;
  edges.reserve(3 * brick.mesh.faces.size());
  for (const Face& t : brick.mesh.faces)
    for (std::size_t i = 0; i < 3; ++i) edges.push_back(key(t[i], t[(i + 1) % 3]));
  std::sort(edges.begin(), edges.end());
  for (std::size_t f = 0; f < brick.mesh.faces.size(); ++f) {
    if (brick.owned[f] == 0) continue;
    const Face& t = brick.mesh.faces[f];
    for (std::size_t i = 0; i < 3; ++i) {
      const auto [lo, hi] = std::equal_range(edges.begin(), edges.end(), key(t[i], t[(i + 1) % 3]));
      if (hi - lo != 2) return false;
    }
  }
  return true;
}

/// Rank 0: every rank's hits, in rank order; elsewhere empty. The counts are agreed first and rank 0
/// makes room for all of them before any is sent (a rank 0 out of memory fails every rank, not one in a
/// send); then each rank sends its hits in chunks of kChunkBytes.
std::vector<ReliefHit> gather_hits(const mpi::Comm& comm, std::vector<ReliefHit> mine) {
  std::vector<double> counts(static_cast<std::size_t>(comm.size()), 0.0);
  counts[static_cast<std::size_t>(comm.rank())] = static_cast<double>(mine.size());
  counts = comm.allreduce(std::move(counts), mpi::ReduceOp::kSum);
  mpi::run_agreed(comm, [&] {
    if (comm.rank() != 0) return;
    double total = 0.0;
    for (const double c : counts) total += c;
    mine.reserve(static_cast<std::size_t>(total));
  });
  if (comm.rank() != 0) {
    const std::span<const std::byte> bytes = std::as_bytes(std::span<const ReliefHit>(mine));
    for (std::size_t at = 0; at < bytes.size(); at += kChunkBytes)
      comm.send(bytes.subspan(at, std::min(kChunkBytes, bytes.size() - at)), 0, kHitsTag);
    return {};
  }
  for (int r = 1; r < comm.size(); ++r) {
    const auto size = static_cast<std::size_t>(counts[static_cast<std::size_t>(r)]) * sizeof(ReliefHit);
    const std::size_t at = mine.size();
    mine.resize(at + size / sizeof(ReliefHit));
    auto* out = reinterpret_cast<std::byte*>(mine.data() + at);
    for (std::size_t got = 0; got < size;) {
      const mpi::Message part = comm.recv(r, kHitsTag);
      if (part.data.empty() || got + part.data.size() > size) throw Error("brick relief: a hit message is too long");
      std::memcpy(out + got, part.data.data(), part.data.size());
      got += part.data.size();
    }
  }
  return mine;
}

/// Rank `root`'s bytes on every rank, in chunks of kChunkBytes.
void broadcast_bytes(const mpi::Comm& comm, std::vector<std::byte>& data) {
  std::vector<double> size{static_cast<double>(data.size())};
  comm.broadcast(size, 0);
  mpi::run_agreed(comm, [&] { data.resize(static_cast<std::size_t>(size[0])); });
  for (std::size_t at = 0; at < data.size(); at += kChunkBytes) {
    std::vector<std::byte> chunk;
    if (comm.rank() == 0)
      chunk.assign(data.begin() + static_cast<std::ptrdiff_t>(at),
                   data.begin() + static_cast<std::ptrdiff_t>(std::min(data.size(), at + kChunkBytes)));
    comm.broadcast(chunk, 0);
    if (comm.rank() != 0) std::copy(chunk.begin(), chunk.end(), data.begin() + static_cast<std::ptrdiff_t>(at));
  }
}

/// Rank 0's texels (distances and normals) on every rank; the layout is already the same everywhere.
void broadcast_texels(const mpi::Comm& comm, ReliefMap& map) {
  std::vector<std::byte> data;
  const std::size_t texels = map.num_layers() * map.texels_per_layer();
  mpi::run_agreed(comm, [&] {
    if (comm.rank() != 0) return;
    data.assign(texels * (sizeof(std::uint16_t) + 3), std::byte{0});
    std::memcpy(data.data(), map.distances.data(), texels * sizeof(std::uint16_t));
    std::memcpy(data.data() + texels * sizeof(std::uint16_t), map.normals.data(), 3 * texels);
  });
  broadcast_bytes(comm, data);
  mpi::run_agreed(comm, [&] {
    if (comm.rank() == 0) return;
    if (data.size() != texels * (sizeof(std::uint16_t) + 3)) throw Error("brick relief: the texels do not match the layout");
    map.distances.resize(texels);
    map.normals.resize(3 * texels);
    std::memcpy(map.distances.data(), data.data(), texels * sizeof(std::uint16_t));
    std::memcpy(map.normals.data(), data.data() + texels * sizeof(std::uint16_t), 3 * texels);
  });
}

/// The map, level by level (steps 3 and 4 of the file comment); on rank 0 with its texels, elsewhere the
/// layout, levels and counts only.
ReliefMap build_map(const mpi::Comm& comm, const BrickMesh& brick, const BoundingBox& box, const ReliefOptions& options,
                    bool closed, const ProgressCallback& progress) {
  // This rank's own faces, numbered as in the file.
  std::vector<Face> own;
  std::vector<std::uint64_t> ids;
  for (std::size_t f = 0; f < brick.mesh.faces.size(); ++f)
    if (brick.owned[f] != 0) {
      own.push_back(brick.mesh.faces[f]);
      ids.push_back(brick.face_ids[f]);
    }
  const MeshView part(brick.mesh.positions, own);
  // As build_relief_map refuses it: nothing would be sampled, and no reader could use the empty map.
  const double area = comm.allreduce(surface_area(part), mpi::ReduceOp::kSum);
  mpi::run_agreed(comm, [&] {
    if (comm.rank() == 0 && !(area > 0.0)) throw InvalidInput("relief map: the mesh has no surface area");
  });
  ReliefMap map;
  std::uint32_t n = options.grid == 0 ? 1 : options.grid;
  while (n != 0) {
    CellGridOptions co;
    co.n = n;
    co.padding = options.padding;
    co.inside_test = options.inside_test;
    const bool parity = !(closed && options.inside_test == InsideTest::Automatic);
    auto t0 = Clock::now();
    CellFaceParts parts;
    mpi::run_agreed(comm, [&] {
      report_progress(progress, "relief cells", 0.0);
      parts = cell_face_parts(part, box, co, parity);
    });
    comm.allreduce_bits(parts.grey, mpi::ReduceOp::kBitOr);
    if (parity) {
      comm.allreduce_bits(parts.toggles, mpi::ReduceOp::kBitXor);
      for (auto& line : parts.line_parity) comm.allreduce_bits(line, mpi::ReduceOp::kBitXor);
    }
    CellGrid grid;
    mpi::run_agreed(comm, [&] {
      grid = finish_cell_grid(std::move(parts), closed, co);
      set_relief_layout(map, grid, options.texture);
      report_progress(progress, "relief cells", 1.0);
    });
    map.seconds_cells += since(t0);
    t0 = Clock::now();
    std::vector<ReliefHit> hits;
    mpi::run_agreed(comm, [&] { hits = sample_relief_hits(map, part, grid, ids); });
    grid = {};
    hits = gather_hits(comm, std::move(hits));
    std::vector<double> counts{0.0, 0.0};
    mpi::run_agreed(comm, [&] {
      if (comm.rank() != 0) return;
      tbb::parallel_sort(hits.begin(), hits.end(), [](const ReliefHit& a, const ReliefHit& b) {
        return a.texel != b.texel ? a.texel < b.texel : a.face < b.face;
      });
      const ReliefSampleCounts c = resolve_relief_hits(map, hits);
      counts = {static_cast<double>(c.samples), static_cast<double>(c.occluded)};
      report_progress(progress, "relief sampling", 1.0);
    });
    hits = {};
    comm.broadcast(counts, 0);  // integers below 2^53
    EdgeOnCounts edge_on;
    mpi::run_agreed(comm, [&] { edge_on = count_edge_on_faces(map, part); });  // each face once: its owner's
    std::vector<double> edge{static_cast<double>(edge_on.faces), static_cast<double>(edge_on.edge_on)};
    edge = comm.allreduce(std::move(edge), mpi::ReduceOp::kSum);  // integers below 2^53: exact
    map.seconds_sampling += since(t0);
    ReliefGridLevel level;
    level.n = n;
    level.grey_cells = map.cells.size();
    level.domain_faces = map.num_layers();
    level.samples = static_cast<std::uint64_t>(counts[0]);
    level.occluded = static_cast<std::uint64_t>(counts[1]);
    level.faces = static_cast<std::uint64_t>(edge[0]);
    level.edge_on = static_cast<std::uint64_t>(edge[1]);
    map.levels.push_back(level);
    spdlog::debug("rank {}: relief level N = {}: {} layers, {} samples, {} occluded; {:.0f} MB resident", comm.rank(), n,
                  map.num_layers(), level.samples, level.occluded, resident_mb());
    n = next_relief_grid(options, level);
  }
  return map;
}

/// Step 5: relief_fidelity of the scan against the map's reconstruction, by bricks. Every rank's `map` holds
/// the texels. Rank 0 gets the result.
ReliefFidelity brick_fidelity(const mpi::Comm& comm, const EmbreeDevice& device, const ScannedMesh& scanned,
                              const Vec3& origin, const BrickMesh& brick, const BrickSamples& scan_samples,
                              const ReliefMap& map, const HausdorffOptions& options) {
  std::optional<ReliefReconstructionIndex> index;
  mpi::run_agreed(comm, [&] {
    try {
      index.emplace(device, map);
    } catch (const InvalidInput& e) {  // as convert_mesh says it: finer texels give a coarse map triangles
      if (std::string_view(e.what()).find("reconstructs to no") == std::string_view::npos) throw;
      throw InvalidInput(fmt::format("{}{}", e.what(), coarse_relief_hint(map.cell_size, map.texture)));
    }
  });
  ReliefFidelity out;
  out.reconstruction_vertices = index->referenced_vertices();
  out.reconstruction_faces = index->faces();
  HausdorffResult& h = out.hausdorff;
  h.diag = BoundingBox{scanned.box.min - origin, scanned.box.max - origin}.diagonal();
  const std::size_t n = scan_samples.points.size();
  const bool root = comm.rank() == 0;

  // Scan -> reconstruction: the area samples in whole blocks per rank (the same distances as one call), the
  // scan's vertices by slices for the maximum.
  std::vector<double> mine;
  double vertex_max = 0.0;
  mpi::run_agreed(comm, [&] {
    const std::size_t blocks = (n + kDistanceBlock - 1) / kDistanceBlock;
    const auto [b0, b1] = slice_of(blocks, comm.rank(), comm.size());
    const std::size_t first = std::min(n, static_cast<std::size_t>(b0) * kDistanceBlock);
    const std::size_t last = std::min(n, static_cast<std::size_t>(b1) * kDistanceBlock);
    mine = index->distances(std::span<const Vec3>(scan_samples.points).subspan(first, last - first),
                            root ? options.progress : ProgressCallback{}, "distance A->B");
    if (!options.include_vertices) return;
    const auto [v0, v1] = slice_of(scanned.file->vertices(), comm.rank(), comm.size());
    std::vector<Vec3> batch;
    const auto flush = [&] {
      for (const double d : index->distances(batch, {}, "distance A->B")) vertex_max = std::max(vertex_max, d);
      batch.clear();
    };
    scanned.file->read_vertices(v0, v1, [&](std::uint64_t at, std::span<const Vec3> p) {
      for (std::size_t i = 0; i < p.size(); ++i) {
        if (!scanned.referenced[at + i]) continue;
        batch.push_back(p[i] - origin);
        if (batch.size() == kVertexBatch) flush();
      }
    });
    flush();
  });
  const std::vector<double> area = gather_at_root(comm, std::move(mine));
  vertex_max = comm.allreduce(vertex_max, mpi::ReduceOp::kMax);
  spdlog::debug("rank {}: scan -> reconstruction measured; {:.0f} MB resident", comm.rank(), resident_mb());
  if (root) {
    h.ab = summarize_distances(area, n);
    h.ab.max = std::max(h.ab.max, vertex_max);
    h.ab.vertex_samples = options.include_vertices ? static_cast<std::size_t>(scanned.vertices) : 0;
  }
  index->release_distances();

  // Reconstruction -> scan: its area samples answered by the bricks of the scan.
  std::optional<TriangleBvh> bvh;
  std::vector<Vec3> points;
  mpi::run_agreed(comm, [&] {
    points = index->area_samples(options.samples, options.seed);
    if (!brick.mesh.faces.empty()) bvh.emplace(device, brick.mesh);
  });
  const TriangleBvh* target = bvh ? &*bvh : nullptr;
  spdlog::debug("rank {}: the brick's BVH built; {:.0f} MB resident", comm.rank(), resident_mb());
  const std::vector<double> back = brick_distances(comm, brick, target, points, "distance B->A");
  points = {};
  spdlog::debug("rank {}: reconstruction -> scan measured; {:.0f} MB resident", comm.rank(), resident_mb());
  std::vector<double> back_max{0.0};
  if (root) {
    h.ba = summarize_distances(back, options.samples);
    back_max[0] = h.ba.max;
  }
  comm.broadcast(back_max, 0);
  if (options.include_vertices) {
    if (back_max[0] < index->vertex_bound())  // rare: the area samples all lie that close to the scan
      index->for_each_vertex_batch([&](std::span<const Vec3> batch) {
        for (const double d : brick_distances(comm, brick, target, batch, "distance B->A")) h.ba.max = std::max(h.ba.max, d);
      });
    h.ba.vertex_samples = index->referenced_vertices();
  }
  h.max = std::max(h.ab.max, h.ba.max);
  h.rms = std::sqrt((h.ab.rms * h.ab.rms + h.ba.rms * h.ba.rms) / 2.0);
  h.psnr = psnr_db(h.diag, h.rms);
  return out;
}

}  // namespace

bool converts_relief_in_bricks(const mpi::Comm& comm, const std::filesystem::path& mesh, const ConversionRequest& request) {
  if (comm.size() < 2 || request.method.method != Method::Relief) return false;
  const std::optional<io::PlyTriangleFile> file = io::PlyTriangleFile::open(mesh);
  return file && file->positions_only();
}

Conversion brick_relief(const mpi::Comm& comm, const EmbreeDevice& device, const std::filesystem::path& mesh,
                        const ConversionRequest& request) {
  const auto start = Clock::now();
  const bool root = comm.rank() == 0;
  const ProgressCallback progress = root ? request.progress : ProgressCallback{};
  const std::string stamp = io::file_stamp(mesh);  // before the first read (require_unchanged)
  std::optional<io::PlyTriangleFile> file;
  ReliefOptions options;
  mpi::run_agreed(comm, [&] {
    options = relief_options(request);
    options.progress = {};
    check_relief_options(options);
    file = io::PlyTriangleFile::open(mesh);
    if (!file) throw InvalidInput(fmt::format("{}: not a binary PLY of triangles readable in pieces", mesh.string()));
  });
  ScannedMesh scanned = scan_mesh(comm, *file);
  const Vec3 center = scanned.box.center();
  const Vec3 origin = center.allFinite() ? center : Vec3::Zero();
  // The fidelity's samples of the scan also give its longest edge, which the ghost layer needs; without
  // the fidelity (a surface without area converts then, as in one process) the edge alone.
  HausdorffOptions h;
  h.samples = request.fidelity.samples;
  h.progress = progress;
  BrickSamples scan_samples;
  const auto sample_scan = [&] {
    if (request.fidelity.enabled)
      scan_samples = brick_samples(comm, scanned, origin, h);
    else
      scan_samples.longest_edge = scan_longest_edge(comm, scanned, origin);
  };
  sample_scan();
  BrickMesh brick = read_brick(comm, scanned, origin, {0.005, scan_samples.longest_edge, true});
  spdlog::debug("rank {}: brick of {} faces read at {:.1f} s; {:.0f} MB resident", comm.rank(), brick.mesh.num_faces(),
                since(start), resident_mb());
  // Exact duplicate faces go, as the loader's repair removes them: the samples are then drawn again without.
  if (drop_duplicate_faces(comm, scanned, brick) && request.fidelity.enabled) sample_scan();
  if (root) warn_repairs(scanned);
  Conversion c;
  mpi::run_agreed(comm, [&] {
    c = begin_conversion(request, static_cast<std::size_t>(scanned.vertices), static_cast<std::size_t>(scanned.faces), origin);
  });
  bool closed = false;
  mpi::run_agreed(comm, [&] { closed = own_edges_closed(brick); });
  spdlog::debug("rank {}: edges checked; {:.0f} MB resident", comm.rank(), resident_mb());
  closed = comm.allreduce(std::int64_t{closed ? 1 : 0}, mpi::ReduceOp::kMin) == 1;
  const BoundingBox box{scanned.box.min - origin, scanned.box.max - origin};
  ReliefMap map;
  name_errors(request.source, [&] { map = build_map(comm, brick, box, options, closed, progress); });
  brick.owned = {};  // what the fidelity does not need
  brick.face_ids = {};
  spdlog::debug("rank {}: map built at {:.1f} s; {:.0f} MB resident", comm.rank(), since(start), resident_mb());
  const double seconds_construct = since(start);
  double seconds_metric = 0.0;
  std::optional<ReliefFidelity> fidelity;
  if (request.fidelity.enabled) {
    const auto metric_start = Clock::now();
    broadcast_texels(comm, map);
    name_errors(request.source, [&] { fidelity = brick_fidelity(comm, device, scanned, origin, brick, scan_samples, map, h); });
    seconds_metric = since(metric_start);
  }
  require_unchanged(comm, mesh, file->shown(), stamp);
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  const double peak_mb = comm.allreduce(static_cast<double>(usage.ru_maxrss) / 1024.0, mpi::ReduceOp::kMax);
  if (!root) return c;
  c.relief = std::move(map);
  record_relief(c);
  if (fidelity) {
    record_fidelity(c, fidelity->hausdorff);
    c.numbers["reconstruction_vertices"] = static_cast<double>(fidelity->reconstruction_vertices);
    c.numbers["reconstruction_faces"] = static_cast<double>(fidelity->reconstruction_faces);
  }
  c.numbers["rank_peak_rss_mb"] = peak_mb;
  finish_conversion(c, seconds_construct, seconds_metric, since(start));
  return c;
}

}  // namespace gimforge::jobs
