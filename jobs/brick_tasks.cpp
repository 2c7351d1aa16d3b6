#include "jobs/brick_tasks.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <span>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <iterator>
#include <optional>
#include <random>

#include <fmt/format.h>

#include "io/atomic_file.h"
#include "io/input_file.h"
#include "io/ply_ranges.h"
#include "jobs/bytes.h"
#include "jobs/proxy_bricks.h"
#include "jobs/scan_bricks.h"
#include "kernels/core/errors.h"
#include "mpi/comm.h"

namespace gimforge::jobs {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr std::string_view kPlanMagic = "gimforge brick plan 1\n";
constexpr std::string_view kPieceMagic = "gimforge brick piece 1\n";

double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// io::file_identity of a source as the plan stores it; IoError when it cannot be stat'ed.
std::vector<std::uint64_t> file_identity(const fs::path& path) {
  const auto id = io::file_identity(path);
  if (!id) throw IoError(fmt::format("{}: cannot stat", path.string()));
  return {(*id)[0], (*id)[1]};
}

/// FNV-1a over the bytes: a plan or piece damaged on disk is planned or made again, never used.
std::uint64_t checksum(std::span<const std::byte> bytes) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (const std::byte c : bytes) h = (h ^ std::to_integer<std::uint64_t>(c)) * 0x100000001b3ULL;
  return h;
}

io::PlyTriangleFile open_scan(const fs::path& source) {
  std::optional<io::PlyTriangleFile> file = io::PlyTriangleFile::open(source);
  if (!file) throw FormatError(fmt::format("{}: not a binary PLY of triangles readable in pieces", source.string()));
  return std::move(*file);
}

/// Everything the piece and finish tasks need, as the plan file holds it.
struct BrickPlan {
  std::vector<std::uint64_t> identity;  ///< file_identity of the source
  std::uint64_t nonce{0};               ///< random, recorded by every piece made from this plan
  std::uint64_t file_vertices{0}, file_faces{0};
  Vec3 origin{Vec3::Zero()};
  std::uint64_t target{0};
  std::uint64_t requested_bricks{0};  ///< the bricks asked for (the proxy_bricks number)
  std::uint64_t scan_faces{0};        ///< kept faces
  std::vector<std::uint64_t> dropped;
  ProxyBricks bricks;
};

/// Writes `bytes` and their checksum atomically.
void write_file(const fs::path& path, Bytes& bytes) {
  bytes.put(std::vector<std::uint64_t>{checksum(bytes.data)});
  io::write_atomically(path, [&](const fs::path& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data.data()), static_cast<std::streamsize>(bytes.data.size()));
    out.close();
    if (!out) throw IoError(fmt::format("{}: cannot write", tmp.string()));
  }, io::ParentDirectory::kMustExist);  // the coordinator makes the folder; a worker it gave up on never remakes it
}

/// The bytes of the work file at `path` after its magic line, checksum verified. StaleBricks when it is
/// missing, not a regular file (links are not followed), longer than `max_bytes`, unreadable, of another
/// kind, or damaged.
Bytes read_file(const fs::path& path, std::string_view magic, std::uint64_t max_bytes) {
  const auto stale = [&](const std::string& why) { throw StaleBricks(fmt::format("{}: {}", path.string(), why)); };
  const int fd = ::open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) stale(fmt::format("cannot open: {}", std::strerror(errno)));
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) stale("not a regular file");
  const auto length = static_cast<std::uint64_t>(st.st_size);
  if (length > max_bytes) stale(fmt::format("{} bytes, more than such a file of this scan can hold", length));
  Bytes b;
  b.what = path.string();
  b.data.assign(static_cast<std::size_t>(length), std::byte{0});
  for (std::size_t done = 0; done < b.data.size();) {
    const ssize_t got = ::pread(fd, b.data.data() + done, b.data.size() - done, static_cast<off_t>(done));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) stale("cannot read");
    done += static_cast<std::size_t>(got);
  }
  if (b.data.size() < magic.size() + 16 ||
      !std::equal(magic.begin(), magic.end(), b.data.begin(), [](char c, std::byte x) { return std::byte(c) == x; }))
    stale(fmt::format("not a {}", magic.substr(9, magic.size() - 12)));
  std::uint64_t stored = 0;
  std::memcpy(&stored, b.data.data() + b.data.size() - 8, 8);
  b.data.resize(b.data.size() - 16);  // the checksum, a vector of one
  if (checksum(b.data) != stored) stale("damaged (its checksum does not match)");
  b.at = magic.size();
  return b;
}

void put_magic(Bytes& b, std::string_view magic) { b.put_raw(magic.data(), magic.size()); }

void write_plan(const fs::path& path, const BrickPlan& p) {
  Bytes b;
  put_magic(b, kPlanMagic);
  b.put(p.identity);
  b.put(std::vector<std::uint64_t>{p.nonce});
  b.put(std::vector<std::uint64_t>{p.file_vertices, p.file_faces, p.target, p.requested_bricks, p.scan_faces,
                                   p.bricks.bricks});
  b.put(std::vector<double>{p.origin.x(), p.origin.y(), p.origin.z()});
  b.put(p.dropped);
  b.put(p.bricks.brick_faces);
  b.put(p.bricks.brick_of_vertex);
  b.put(p.bricks.seam);
  write_file(path, b);
}

/// The plan at `path` for the scan `file` opened from `source`; StaleBricks when it does not read back, does
/// not describe this file (counts, identity) or contradicts itself.
BrickPlan parse_plan(const fs::path& path, const io::PlyTriangleFile& file, const fs::path& source) {
  // At most: two marks per vertex, every face dropped, 64 bricks, headers.
  Bytes b = read_file(path, kPlanMagic, 2 * file.vertices() + 8 * file.faces() + 4096);
  BrickPlan p;
  p.identity = b.get<std::uint64_t>();
  const std::vector<std::uint64_t> nonce = b.get<std::uint64_t>();
  if (nonce.size() != 1) b.short_of("its header");
  p.nonce = nonce[0];
  const std::vector<std::uint64_t> sizes = b.get<std::uint64_t>();
  const std::vector<double> origin = b.get<double>();
  if (sizes.size() != 6 || origin.size() != 3) b.short_of("its header");
  p.file_vertices = sizes[0];
  p.file_faces = sizes[1];
  p.target = sizes[2];
  p.requested_bricks = sizes[3];
  p.scan_faces = sizes[4];
  p.bricks.bricks = static_cast<std::size_t>(std::min<std::uint64_t>(sizes[5], kMaxBricks + 1));
  p.origin = Vec3(origin[0], origin[1], origin[2]);
  p.dropped = b.get<std::uint64_t>();
  p.bricks.brick_faces = b.get<std::uint64_t>();
  p.bricks.brick_of_vertex = b.get<std::uint8_t>();
  p.bricks.seam = b.get<std::uint8_t>();
  const auto bad = [&](const char* what) { throw StaleBricks(fmt::format("{}: {}", path.string(), what)); };
  if (b.at != b.data.size()) bad("trailing bytes");
  if (p.identity != file_identity(source)) throw StaleBricks(fmt::format("{}: {}", source.string(), kStaleBricks));
  if (p.file_vertices != file.vertices() || p.file_faces != file.faces()) bad("made for a file of other counts");
  if (p.bricks.bricks > kMaxBricks || p.bricks.brick_faces.size() != p.bricks.bricks) bad("brick counts do not agree");
  if (p.bricks.brick_of_vertex.size() != p.file_vertices || p.bricks.seam.size() != p.file_vertices)
    bad("vertex marks do not cover the file's vertices");
  for (const std::uint8_t v : p.bricks.brick_of_vertex)
    if (v != kNoBrick && v >= p.bricks.bricks) bad("a vertex names no brick");
  for (const std::uint8_t v : p.bricks.seam)
    if (v != kNoBrick && v != kSeamVertex && v >= p.bricks.bricks) bad("a seam mark names no brick");
  for (std::size_t i = 0; i < p.dropped.size(); ++i)
    if (p.dropped[i] >= p.file_faces || (i > 0 && p.dropped[i] <= p.dropped[i - 1])) bad("dropped faces out of order");
  std::uint64_t sum = 0;
  for (const std::uint64_t f : p.bricks.brick_faces) sum += std::min<std::uint64_t>(f, p.file_faces);
  if (p.scan_faces > p.file_faces || (p.bricks.bricks > 0 && sum != p.scan_faces)) bad("face counts do not agree");
  return p;
}

BrickPlan read_plan(const fs::path& path, const io::PlyTriangleFile& file, const fs::path& source) {
  try {
    return parse_plan(path, file, source);
  } catch (const StaleBricks&) {
    throw;
  } catch (const FormatError& e) {  // short arrays (Bytes)
    throw StaleBricks(e.what());
  }
}

}  // namespace

bool converts_by_brick_tasks(const fs::path& source, const MethodOptions& method) noexcept {
  try {
    if (method.method == Method::Relief) return false;
    const std::optional<io::PlyTriangleFile> file = io::PlyTriangleFile::open(source);
    if (!file) return false;
    const auto faces = static_cast<std::size_t>(file->faces());
    const std::size_t target = method.proxy_target(faces);
    if (target == 0) return false;
    return (method.proxy_bricks > 0 ? method.proxy_bricks : proxy_bricks(faces, target)) > 1;
  } catch (...) {
    return false;
  }
}

std::vector<std::uint64_t> find_duplicate_faces(const io::PlyTriangleFile& file, std::size_t keys_per_pass) {
  const std::uint64_t passes = std::max<std::uint64_t>(1, (file.faces() + keys_per_pass - 1) / std::max<std::size_t>(keys_per_pass, 1));
  std::vector<std::uint64_t> dropped;
  struct Key {
    std::array<std::uint32_t, 3> v;
    std::uint64_t face;
  };
  for (std::uint64_t pass = 0; pass < passes; ++pass) {
    std::vector<Key> keys;
    file.read_faces(0, file.faces(), [&](std::uint64_t at, std::span<const Face> faces) {
      for (std::size_t i = 0; i < faces.size(); ++i) {
        if (has_repeated_index(faces[i])) continue;
        std::array<std::uint32_t, 3> v = faces[i];
        std::sort(v.begin(), v.end());
        if (v[0] % passes == pass) keys.push_back({v, at + i});
      }
    });
    std::sort(keys.begin(), keys.end(), [](const Key& a, const Key& b) { return a.v != b.v ? a.v < b.v : a.face < b.face; });
    for (std::size_t i = 1; i < keys.size(); ++i)
      if (keys[i].v == keys[i - 1].v) dropped.push_back(keys[i].face);
  }
  std::sort(dropped.begin(), dropped.end());
  return dropped;
}

fs::path brick_plan_file(const fs::path& dir) { return dir / "plan.bin"; }
fs::path brick_piece_file(const fs::path& dir, std::size_t brick) { return dir / fmt::format("{}.bin", brick); }

BrickPlanSummary plan_brick_tasks(const fs::path& source, const MethodOptions& method, const fs::path& dir) {
  BrickPlan plan;
  plan.identity = file_identity(source);  // before reading: a file replaced meanwhile makes the plan stale
  const io::PlyTriangleFile file = open_scan(source);
  // Pieces of an earlier plan of this item (its source changed) must never pass for this plan's.
  std::random_device entropy;
  plan.nonce = (std::uint64_t{entropy()} << 32) ^ std::uint64_t{entropy()};
  const mpi::Comm alone = mpi::Comm::serial();
  ScannedMesh scanned = scan_mesh(alone, file);
  const Vec3 center = scanned.box.center();
  plan.origin = center.allFinite() ? center : Vec3::Zero();
  scanned.dropped = find_duplicate_faces(file);
  scanned.faces -= scanned.dropped.size();
  plan.file_vertices = file.vertices();
  plan.file_faces = file.faces();
  plan.scan_faces = scanned.faces;
  plan.dropped = scanned.dropped;
  plan.target = method.proxy_target(static_cast<std::size_t>(scanned.faces));
  if (plan.target > 0) {
    // As convert makes the proxy in one process (jobs/proxy.cpp make_proxy) and by ranks (brick_convert.cpp).
    const std::size_t requested = std::min<std::size_t>(
        method.proxy_bricks > 0 ? method.proxy_bricks : proxy_bricks(scanned.faces, plan.target), kMaxProxyBricks);
    plan.requested_bricks = requested;
    if (requested > 1)
      plan.bricks = assign_proxy_bricks(scanned, vertex_bricks(alone, scanned, plan.origin, requested), plan.origin, {});
  }
  if (plan.bricks.bricks == 0) {  // converted whole: no marks needed
    plan.bricks.brick_of_vertex.assign(static_cast<std::size_t>(plan.file_vertices), kNoBrick);
    plan.bricks.seam.assign(static_cast<std::size_t>(plan.file_vertices), kNoBrick);
  }
  write_plan(brick_plan_file(dir), plan);
  if (file_identity(source) != plan.identity)  // rewritten while it was read
    throw StaleBricks(fmt::format("{}: {}", source.string(), kStaleBricks));
  return {plan.bricks.brick_faces, plan.nonce, plan.file_vertices};
}

BrickPlanSummary read_brick_plan(const fs::path& dir, const fs::path& source) {
  BrickPlan plan = read_plan(brick_plan_file(dir), open_scan(source), source);
  return {std::move(plan.bricks.brick_faces), plan.nonce, plan.file_vertices};
}

void decimate_brick_task(const fs::path& source, const fs::path& dir, std::size_t brick) {
  const auto start = Clock::now();
  const fs::path plan_path = brick_plan_file(dir);
  const io::PlyTriangleFile file = open_scan(source);
  const BrickPlan plan = read_plan(plan_path, file, source);
  if (brick >= plan.bricks.bricks)
    throw StaleBricks(fmt::format("{}: brick {} of a plan of {}", plan_path.string(), brick, plan.bricks.bricks));
  std::vector<Face> faces;
  faces.reserve(static_cast<std::size_t>(plan.bricks.brick_faces[brick]));  // at most the file's faces (read_plan)
  file.read_faces(0, file.faces(), [&](std::uint64_t at, std::span<const Face> chunk) {
    for (std::size_t i = 0; i < chunk.size(); ++i) {
      const Face& t = chunk[i];
      if (has_repeated_index(t) || plan.bricks.brick_of_vertex[t[0]] != brick) continue;
      if (!plan.dropped.empty() && std::binary_search(plan.dropped.begin(), plan.dropped.end(), at + i)) continue;
      faces.push_back(t);
    }
  });
  const DecimatedPiece piece = decimate_brick(file, faces, plan.bricks, plan.origin, static_cast<std::size_t>(plan.target),
                                              plan.scan_faces);
  Bytes b;
  put_magic(b, kPieceMagic);
  b.put(std::vector<double>{since(start)});
  b.put(std::vector<std::uint64_t>{plan.nonce});
  put_piece(b, brick, piece);
  write_file(brick_piece_file(dir, brick), b);
}

namespace {

/// A piece file: its seconds and the piece, checked to be brick `brick`'s (of at most `faces` faces) of the
/// plan with `nonce` over `vertices` file vertices. StaleBricks otherwise.
std::pair<double, DecimatedPiece> read_piece(const fs::path& path, std::size_t brick, std::uint64_t nonce,
                                             std::uint64_t faces, std::uint64_t vertices) {
  const auto stale = [&](const std::string& why) { throw StaleBricks(fmt::format("{}: {}", path.string(), why)); };
  try {
    Bytes b = read_file(path, kPieceMagic, 64 * faces + 4096);
    const std::vector<double> seconds = b.get<double>();
    const std::vector<std::uint64_t> made_from = b.get<std::uint64_t>();
    if (seconds.size() != 1 || made_from.size() != 1) b.short_of("its header");
    if (made_from[0] != nonce) stale("made from an earlier plan");
    auto [id, piece] = get_piece(b);
    if (id != brick) stale(fmt::format("holds brick {}, expected {}", id, brick));
    if (b.at != b.data.size()) stale("trailing bytes");
    if (!piece.ids.empty() && piece.ids.back() >= vertices) stale("names a vertex the scan does not have");
    return {seconds[0], std::move(piece)};
  } catch (const FormatError& e) {  // get_piece's
    throw StaleBricks(e.what());
  }
}

}  // namespace

void check_brick_piece(const fs::path& dir, std::size_t brick, const BrickPlanSummary& plan) {
  if (brick >= plan.brick_faces.size()) throw StaleBricks(fmt::format("{}: no brick {}", dir.string(), brick));
  (void)read_piece(brick_piece_file(dir, brick), brick, plan.nonce, plan.brick_faces[brick], plan.vertices);
}

ProxyMaker proxy_from_pieces(const fs::path& source, const fs::path& dir) {
  return [source, dir](const TriMesh& local, const Vec3& origin, std::size_t target, const ProgressCallback& progress,
                       std::map<std::string, double>& numbers) {
    const auto start = Clock::now();
    const BrickPlan plan = read_plan(brick_plan_file(dir), open_scan(source), source);
    if (plan.origin != origin || plan.target != target || plan.scan_faces != local.num_faces())
      throw StaleBricks(fmt::format("{}: {} (its frame, proxy size or face count differ)", source.string(), kStaleBricks));
    std::vector<DecimatedPiece> present;
    double seconds = 0.0;
    for (std::size_t b = 0; b < plan.bricks.bricks; ++b) {
      if (plan.bricks.brick_faces[b] == 0) continue;
      auto [s, piece] = read_piece(brick_piece_file(dir, b), b, plan.nonce, plan.bricks.brick_faces[b], plan.file_vertices);
      seconds += s;
      present.push_back(std::move(piece));
    }
    TriMesh proxy = finish_proxy(std::move(present), plan.file_vertices, target,
                                 static_cast<std::size_t>(plan.requested_bricks), progress, numbers);
    numbers["seconds_proxy"] = seconds + since(start);  // the pieces' decimation, on whichever workers, and this
    return proxy;
  };
}

}  // namespace gimforge::jobs
