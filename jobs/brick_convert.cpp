#include "jobs/brick_convert.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstring>
#include <limits>
#include <optional>
#include <sys/resource.h>
#include <unistd.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "io/atomic_file.h"
#include "io/input_file.h"
#include "io/mesh_io.h"
#include "io/ply_ranges.h"
#include "jobs/brick_metrics.h"
#include "jobs/error_naming.h"
#include "jobs/proxy.h"
#include "jobs/proxy_bricks.h"
#include "jobs/scan_bricks.h"
#include "kernels/core/errors.h"
#include "kernels/scan/decimate.h"
#include "kernels/scan/surface_transfer.h"
#include "mpi/agree.h"

namespace gimforge::jobs {
namespace {

using Clock = std::chrono::steady_clock;
constexpr int kPieceTag = 71;

double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// Step 1: the proxy on rank 0 (the others return an empty mesh). Adds the proxy numbers to `numbers`.
TriMesh distributed_proxy(const mpi::Comm& comm, const ScannedMesh& scanned, const Vec3& origin, std::size_t target,
                          std::size_t brick_count, const ProgressCallback& progress,
                          std::map<std::string, double>& numbers) {
  const auto start = Clock::now();
  const io::PlyTriangleFile& file = *scanned.file;
  const std::size_t bricks = std::min<std::size_t>(brick_count > 0 ? brick_count : proxy_bricks(scanned.faces, target), 64);
  const BrickPartition partition = vertex_bricks(comm, scanned, origin, bricks);
  const auto size = static_cast<std::size_t>(comm.size()), rank = static_cast<std::size_t>(comm.rank());
  std::vector<std::vector<Face>> mine(bricks);
  ProxyBricks assigned;
  mpi::run_agreed(comm, [&] {
    assigned = assign_proxy_bricks(scanned, partition, origin, [&](std::uint8_t b, const Face& t) {
      if (b % size == rank) mine[b].push_back(t);
    });
  });
  // This rank's bricks, each decimated on its own.
  Bytes outgoing;
  std::vector<std::pair<std::uint64_t, DecimatedPiece>> own;
  mpi::run_agreed(comm, [&] {
    for (std::size_t b = rank; b < bricks; b += size) {
      if (mine[b].empty()) continue;
      DecimatedPiece piece = decimate_brick(file, mine[b], assigned, origin, target, scanned.faces);
      mine[b] = {};
      if (rank == 0)
        own.emplace_back(b, std::move(piece));
      else
        put_piece(outgoing, b, piece);
      report_progress(progress, "decimate", 0.8 * static_cast<double>(b + 1) / static_cast<double>(bricks));
    }
  });
  spdlog::debug("rank {}: decimated its bricks in {:.2f} s", comm.rank(), since(start));
  // Rank 0 gathers the pieces in brick order.
  // Sizes agreed first, so that no rank fails in a send the others wait for.
  const double largest = comm.allreduce(static_cast<double>(outgoing.data.size()), mpi::ReduceOp::kMax);
  mpi::run_agreed(comm, [&] {
    if (rank == 0 && largest >= static_cast<double>(std::numeric_limits<int>::max()))
      throw InvalidInput(fmt::format("{}: a rank's decimated bricks take {:.0f} bytes, more than one message holds; "
                                     "use a smaller --proxy-faces or more ranks",
                                     file.shown(), largest));
  });
  std::vector<std::vector<std::byte>> received;
  if (rank != 0) {
    comm.send(outgoing.data, 0, kPieceTag);
  } else {
    for (int r = 1; r < comm.size(); ++r) received.push_back(comm.recv(r, kPieceTag).data);
  }
  outgoing = {};
  std::vector<DecimatedPiece> pieces(bricks);
  std::vector<std::uint8_t> have(bricks, 0);
  TriMesh proxy;
  mpi::run_agreed(comm, [&] {
    if (rank != 0) return;
    for (auto& [b, piece] : own) {
      pieces[b] = std::move(piece);
      have[b] = 1;
    }
    for (std::vector<std::byte>& data : received) {
      Bytes in{std::move(data), 0, "brick convert: a piece message"};
      while (in.at < in.data.size()) {
        auto [b, piece] = get_piece(in);
        if (b >= bricks) throw Error("brick convert: a piece names no brick");
        pieces[b] = std::move(piece);
        have[b] = 1;
      }
    }
    std::vector<DecimatedPiece> present;
    for (std::size_t b = 0; b < bricks; ++b)
      if (have[b] != 0) present.push_back(std::move(pieces[b]));
    proxy = finish_proxy(std::move(present), file.vertices(), target, bricks, progress, numbers);
    numbers["seconds_proxy"] = since(start);
  });
  return proxy;
}

void broadcast_mesh(const mpi::Comm& comm, TriMesh& mesh) {
  Bytes b;
  if (comm.rank() == 0) {
    b.put(mesh.positions);
    b.put(mesh.faces);
  }
  comm.broadcast(b.data, 0);
  if (comm.rank() != 0) {
    mesh.positions = b.get<Vec3>();
    mesh.faces = b.get<Face>();
  }
}

/// The least candidate over the ranks, per point (ties: the lowest rank).
std::vector<TransferCandidate> least(const mpi::Comm& comm, const std::vector<TransferCandidate>& mine) {
  const std::size_t n = mine.size();
  std::vector<double> d(n);
  for (std::size_t i = 0; i < n; ++i) d[i] = mine[i].distance;
  const std::vector<double> best = comm.allreduce(d, mpi::ReduceOp::kMin);
  std::vector<double> winner(n);
  for (std::size_t i = 0; i < n; ++i)
    winner[i] = d[i] == best[i] && std::isfinite(best[i]) ? comm.rank() : std::numeric_limits<double>::infinity();
  winner = comm.allreduce(std::move(winner), mpi::ReduceOp::kMin);
  std::vector<double> values(9 * n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    if (winner[i] != comm.rank()) continue;
    for (Eigen::Index k = 0; k < 3; ++k) {
      values[9 * i + static_cast<std::size_t>(k)] = mine[i].point[k];
      values[9 * i + 3 + static_cast<std::size_t>(k)] = mine[i].normal[k];
      values[9 * i + 6 + static_cast<std::size_t>(k)] = mine[i].barycentric[k];
    }
  }
  values = comm.allreduce(std::move(values), mpi::ReduceOp::kSum);
  std::vector<TransferCandidate> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(best[i])) continue;
    out[i].distance = best[i];
    out[i].point = Vec3(values[9 * i], values[9 * i + 1], values[9 * i + 2]);
    out[i].normal = Vec3(values[9 * i + 3], values[9 * i + 4], values[9 * i + 5]);
    out[i].barycentric = Vec3(values[9 * i + 6], values[9 * i + 7], values[9 * i + 8]);
    out[i].face = 0;  // found (the face index is the winning rank's own)
  }
  return out;
}

/// A temporary PLY beside the output, removed when it goes out of scope (rank 0 writes and removes).
struct TemporaryPly {
  std::filesystem::path path;
  bool owner{false};
  io::RemovedOnSignal pending{owner ? path : std::filesystem::path()};
  ~TemporaryPly() {
    if (!owner) return;
    std::error_code ec;
    std::filesystem::remove(path, ec);
  }
};

}  // namespace

bool converts_in_bricks(const mpi::Comm& comm, const std::filesystem::path& mesh, const ConversionRequest& request) {
  if (comm.size() < 2 || request.method.method == Method::Relief || request.sphere_map) return false;
  const std::optional<io::PlyTriangleFile> file = io::PlyTriangleFile::open(mesh);
  return file && request.method.proxy_target(static_cast<std::size_t>(file->faces())) > 0;
}

std::optional<Conversion> brick_convert(const mpi::Comm& comm, const EmbreeDevice& device,
                                        const std::filesystem::path& mesh, const ConversionRequest& request,
                                        const std::filesystem::path& scratch) {
  const auto start = Clock::now();
  const bool root = comm.rank() == 0;
  const ProgressCallback progress = root ? request.progress : ProgressCallback{};
  const std::string stamp = io::file_stamp(mesh);  // before the first read (require_unchanged)
  std::optional<io::PlyTriangleFile> file;
  mpi::run_agreed(comm, [&] {
    file = io::PlyTriangleFile::open(mesh);
    if (!file) throw InvalidInput(fmt::format("{}: not a binary PLY of triangles readable in pieces", mesh.string()));
  });
  ScannedMesh scanned = scan_mesh(comm, *file);
  const Vec3 center = scanned.box.center();
  const Vec3 origin = center.allFinite() ? center : Vec3::Zero();
  // The ghost layer must hold every face around an own face's vertices: twice the scan's longest edge,
  // which the brick reader adds to the margin (jobs/scan_bricks.h).
  const double scan_edge = scan_longest_edge(comm, scanned, origin);
  const auto wrap = request.method.wrap_voxels();
  const std::string wrap_text = wrap ? request.method.wrap : std::string{};  // errors named as the wrap's
  BrickTopology topology;
  {
    // Exact duplicate faces go first, as the loader's repair removes them (one pass over a brick each).
    BrickMesh brick = read_brick(comm, scanned, origin, {0.0, scan_edge, true});
    (void)drop_duplicate_faces(comm, scanned, brick);
    if (!wrap) topology = brick_topology(comm, brick);  // a wrap takes any triangles
  }
  // What the loader refuses or the multi-chart method cuts (load_policy), decided as one process decides it.
  if (!topology.manifold() || !topology.oriented()) {
    if (request.method.method != Method::Mcgim)
      mpi::run_agreed(comm, [&] {
        // The ranks hold the mesh in bricks: the default wrap, unmeasured (error_naming.h).
        const LoadPolicy policy = load_policy(request.method, false);
        throw TopologyError(fmt::format("{}: {}{}{}", file->shown(), topology.first_defect(), policy.refusal_hint,
                                        policy.suggest_wrap ? wrap_clause(nullptr) : std::string{}));
      });
    // The multi-chart method cuts such a mesh to a 2-manifold before its proxy (convert_mesh): rank 0 reads it
    // whole and converts it as one process does.
    if (root)
      spdlog::info("{}: {}: rank 0 reads the mesh whole to cut it to a 2-manifold, as one process does",
                   file->shown(), topology.first_defect());
    return std::nullopt;
  }
  Conversion c;
  std::size_t target = 0;
  mpi::run_agreed(comm, [&] {
    c = begin_conversion(request, static_cast<std::size_t>(scanned.vertices), static_cast<std::size_t>(scanned.faces), origin);
    target = request.method.proxy_target(static_cast<std::size_t>(scanned.faces));
  });
  if (target == 0) return std::nullopt;  // the same on every rank: scanned.faces is
  // Said here, once: where rank 0 reads the mesh whole instead (the returns above), its loader says it.
  if (root) warn_repairs(scanned);
  std::map<std::string, double> proxy_numbers;
  TriMesh proxy;
  name_errors(request.source, [&] {
    proxy = distributed_proxy(comm, scanned, origin, target, request.method.proxy_bricks, progress, proxy_numbers);
  }, wrap_text);
  // Step 2: the method on rank 0.
  std::vector<std::vector<Vec3>> sets;
  mpi::run_agreed(comm, [&] {
    if (!root) return;
    if (wrap)  // --wrap: of the ranks' proxy, as one process does
      name_errors(request.source, [&] {
        proxy = make_wrap_proxy(proxy, wrap->first, wrap->second, request.method.wrap_proxy_target(),
                                request.method.proxy_bricks, request.source, progress, proxy_numbers);
      }, wrap_text);
    warn_proxy_rejections(request.source, proxy_numbers);
    ConversionRequest on_proxy = request;
    on_proxy.method.optimize = false;  // fitted after the transfer, to the full surface (step 3)
    run_method(device, proxy, on_proxy, c, wrap_text);
    c.numbers.merge(proxy_numbers);
    sets = transfer_point_sets(c);
  });
  const auto transfer_start = Clock::now();
  broadcast_mesh(comm, proxy);
  // Step 3: the transfer, by bricks.
  const BrickMesh brick = read_brick(comm, scanned, origin, {0.005, scan_edge, false});
  std::optional<SurfaceTransfer> transfer;
  TransferOptions options;
  options.progress = progress;
  const std::vector<std::uint8_t> none(proxy.num_faces(), 0);
  mpi::run_agreed(comm, [&] {
    if (brick.mesh.faces.empty())
      transfer.emplace(device, proxy, proxy, options, none);  // nothing held: no candidates
    else
      transfer.emplace(device, proxy, brick.mesh, options, brick.owned);
  });
  std::vector<double> count{static_cast<double>(sets.size())};
  comm.broadcast(count, 0);
  std::vector<TransferResult> results;
  for (std::size_t k = 0; k < static_cast<std::size_t>(count[0]); ++k) {
    std::vector<double> flat;
    if (root)
      for (const Vec3& p : sets[k]) flat.insert(flat.end(), {p.x(), p.y(), p.z()});
    comm.broadcast(flat, 0);
    std::vector<Vec3> points(flat.size() / 3);
    for (std::size_t i = 0; i < points.size(); ++i) points[i] = Vec3(flat[3 * i], flat[3 * i + 1], flat[3 * i + 2]);
    TransferCandidates mine;
    mpi::run_agreed(comm, [&] { mine = transfer->candidates(points); });
    TransferCandidates all{least(comm, mine.closest), least(comm, mine.crossing)};
    mpi::run_agreed(comm, [&] {
      if (root) results.push_back(transfer->assemble(points, all));
    });
  }
  transfer.reset();
  mpi::run_agreed(comm, [&] {
    if (!root) return;
    apply_transfers(c, results, nullptr);
    c.numbers["seconds_transfer"] = since(transfer_start);
  });
  if (request.method.optimize) {
    // --optimize against the full surface, as one process fits after its transfer (pipeline.h fit_image): the
    // same area samples, drawn by the ranks each on their slice of the faces.
    std::vector<double> samples{root ? static_cast<double>(fit_reference_samples(c)) : 0.0};
    comm.broadcast(samples, 0);
    HausdorffOptions h;
    h.samples = static_cast<std::size_t>(samples[0]);
    h.seed = fit_reference_seed();
    const BrickSamples reference = brick_samples(comm, scanned, origin, h);
    mpi::run_agreed(comm, [&] {
      if (root) name_errors(request.source, [&] { fit_image(device, reference.points, c, progress); });
    });
  }
  const double seconds_construct = since(start);
  // Step 4: the fidelity, by bricks, against the reconstruction and the proxy written beside the output.
  double seconds_metric = 0.0;
  if (request.fidelity.enabled) {
    const auto metric_start = Clock::now();
    // Rank 0's temporary names (io/atomic_file.h temporary_path: "….<host>.<pid>.tmp"), so that the leftovers
    // of a run that was killed here are removed by the next one, and by a batch's clean-up.
    const std::filesystem::path base = scratch / (".gimforge-" + mesh.stem().string());
    std::array<std::string, 2> names;
    mpi::run_agreed(comm, [&] {
      if (!root) return;
      for (std::size_t k = 0; k < 2; ++k) {
        std::filesystem::path p = base;
        p += k == 0 ? ".reconstruction.ply" : ".proxy.ply";
        try {  // best effort: a leftover we may not remove (another user's) must not fail the conversion
          for (const std::filesystem::path& stale : io::remove_stale_temporaries(p))
            spdlog::debug("removed {}, left by a killed run", stale.string());
        } catch (const IoError& e) {
          spdlog::debug("{}", e.what());
        }
        names[k] = io::temporary_path(p).string();
      }
    });
    for (std::string& name : names) comm.broadcast(name, 0);
    TemporaryPly recon{names[0], root}, proxy_file{names[1], root};
    mpi::run_agreed(comm, [&] {
      if (!root) return;
      TriMesh r = image_reconstruction(c);
      to_input_frame(r, origin);
      io::write_ply(recon.path, r, {.binary = true, .double_precision = true});
      TriMesh p = proxy;
      to_input_frame(p, origin);
      io::write_ply(proxy_file.path, p, {.binary = true, .double_precision = true});
    });
    HausdorffOptions h;
    h.samples = request.fidelity.samples;
    h.progress = progress;
    const HausdorffResult fidelity = brick_hausdorff(comm, device, mesh, recon.path, h, scanned.dropped, false);
    const HausdorffResult of_proxy = brick_hausdorff(comm, device, mesh, proxy_file.path, h, scanned.dropped, false);
    if (root) {
      record_fidelity(c, fidelity);
      c.numbers["proxy_psnr"] = of_proxy.psnr;
    }
    seconds_metric = since(metric_start);
  }
  require_unchanged(comm, mesh, file->shown(), stamp);
  // The largest peak memory of any rank (what the huge-scan targets bound), and each rank's at -v.
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  const double peak_mb = static_cast<double>(usage.ru_maxrss) / 1024.0;
  spdlog::debug("rank {}: peak RSS {:.0f} MB", comm.rank(), peak_mb);
  const double largest = comm.allreduce(peak_mb, mpi::ReduceOp::kMax);
  if (root) c.numbers["rank_peak_rss_mb"] = largest;
  finish_conversion(c, seconds_construct, seconds_metric, since(start));
  return std::optional<Conversion>(std::move(c));
}

}  // namespace gimforge::jobs
