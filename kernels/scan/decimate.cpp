/// \file decimate.cpp
/// OpenMesh's Decimater with the quadric module (priority) and the normal-flipping module (binary). The
/// only translation unit that includes OpenMesh: its templates are instantiated once, here.
#include "kernels/scan/decimate.h"

#include <algorithm>
#include <atomic>
#include <mutex>
#include <unordered_map>

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModAspectRatioT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>
#include <OpenMesh/Tools/Decimater/Observer.hh>
#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include "kernels/core/errors.h"

namespace gimforge {
namespace {

// Double positions: huge scans have millions of vertices in a box where float's 24 bits would merge
// neighbours' quadrics.
struct ProxyTraits : public OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;
  using Normal = OpenMesh::Vec3d;
  VertexAttributes(OpenMesh::Attributes::Status);
  EdgeAttributes(OpenMesh::Attributes::Status);
  HalfedgeAttributes(OpenMesh::Attributes::PrevHalfedge);
  FaceAttributes(OpenMesh::Attributes::Status | OpenMesh::Attributes::Normal);
};
using ProxyMesh = OpenMesh::TriMesh_ArrayKernelT<ProxyTraits>;
using Decimater = OpenMesh::Decimater::DecimaterT<ProxyMesh>;

// Reports every `interval` collapses as a fraction of those needed; a callback that asks to stop aborts the
// decimater, and decimate_quadric then throws Cancelled.
class ProgressObserver : public OpenMesh::Decimater::Observer {
 public:
  ProgressObserver(const ProgressCallback& progress, std::size_t needed)
      : Observer(std::max<std::size_t>(1, needed / 100)), progress_(progress), needed_(std::max<std::size_t>(1, needed)) {}
  void notify(std::size_t step) override {
    if (progress_ && !progress_("decimate", std::min(1.0, static_cast<double>(step) / static_cast<double>(needed_))))
      stop_ = true;
  }
  [[nodiscard]] bool abort() const override { return stop_; }
  [[nodiscard]] bool stopped() const { return stop_; }

 private:
  const ProgressCallback& progress_;
  std::size_t needed_;
  bool stop_{false};
};

void check(MeshView mesh, const DecimateOptions& options) {
  if (options.target_faces == 0) throw InvalidInput("decimate: the target face count must be at least 1");
  if (!options.locked.empty() && options.locked.size() != mesh.positions.size())
    throw InvalidInput(fmt::format("decimate: {} lock flags for {} vertices", options.locked.size(), mesh.positions.size()));
  if (!options.brick_of_face.empty() && options.brick_of_face.size() != mesh.faces.size())
    throw InvalidInput(fmt::format("decimate: {} brick ids for {} faces", options.brick_of_face.size(), mesh.faces.size()));
  for (const std::uint8_t b : options.brick_of_face)
    if (b >= kMaxBricks) throw InvalidInput(fmt::format("decimate: brick id {} is not below {}", b, kMaxBricks));
  if (!(options.max_normal_turn_degrees > 0.0 && options.max_normal_turn_degrees <= 180.0))
    throw InvalidInput(fmt::format("decimate: the normal bound {} degrees is not in (0, 180]", options.max_normal_turn_degrees));
  for (const Face& f : mesh.faces)
    for (const std::uint32_t v : f)
      if (v >= mesh.positions.size())
        throw InvalidInput(fmt::format("decimate: a face names vertex {} of {}", v, mesh.positions.size()));
}

/// OpenMesh reports a face it cannot insert on its (process-wide) error stream; the callers count such faces
/// instead. Silenced while any decimation runs, on any thread.
class QuietOpenMesh {
 public:
  QuietOpenMesh() {
    const std::lock_guard lock(mutex_);
    if (depth_++ == 0) ::omerr().disable();
  }
  ~QuietOpenMesh() {
    const std::lock_guard lock(mutex_);
    if (--depth_ == 0) ::omerr().enable();
  }
  QuietOpenMesh(const QuietOpenMesh&) = delete;
  QuietOpenMesh& operator=(const QuietOpenMesh&) = delete;

 private:
  static inline std::mutex mutex_;
  static inline int depth_ = 0;
};

/// One OpenMesh decimation of the whole of `mesh` (options checked by the caller; OpenMesh's error stream
/// silenced by the caller, as it is shared by threads).
DecimateResult decimate_one(MeshView mesh, const DecimateOptions& options) {
  DecimateResult result;
  ProxyMesh om;
  om.reserve(mesh.positions.size(), mesh.faces.size() * 3 / 2 + 3, mesh.faces.size());
  OpenMesh::VPropHandleT<std::uint32_t> source;
  om.add_property(source);
  std::vector<ProxyMesh::VertexHandle> handles(mesh.positions.size());
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const Vec3& p = mesh.positions[v];
    handles[v] = om.add_vertex(ProxyMesh::Point(p.x(), p.y(), p.z()));
    om.property(source, handles[v]) = static_cast<std::uint32_t>(v);
  }
  for (const Face& f : mesh.faces) {
    if (has_repeated_index(f)) {
      ++result.rejected_faces;
      continue;
    }
    if (!om.add_face(handles[f[0]], handles[f[1]], handles[f[2]]).is_valid()) ++result.rejected_faces;
  }
  if (!options.locked.empty())
    for (std::size_t v = 0; v < handles.size(); ++v)
      if (options.locked[v] != 0) om.status(handles[v]).set_locked(true);
  om.update_face_normals();

  if (om.n_faces() > options.target_faces) {
    Decimater decimater(om);
    OpenMesh::Decimater::ModQuadricT<ProxyMesh>::Handle quadric;
    OpenMesh::Decimater::ModNormalFlippingT<ProxyMesh>::Handle flipping;
    decimater.add(quadric);
    decimater.add(flipping);
    OpenMesh::Decimater::ModAspectRatioT<ProxyMesh>::Handle aspect;
    decimater.add(aspect);
    decimater.module(aspect).set_aspect_ratio(10.0f);
    decimater.module(aspect).set_binary(true);
    decimater.module(quadric).unset_max_err();
    decimater.module(flipping).set_max_normal_deviation(options.max_normal_turn_degrees);
    if (!decimater.initialize()) throw InvalidInput("decimate: OpenMesh's decimater did not initialize");
    // A collapse removes two faces (one at a boundary).
    ProgressObserver observer(options.progress, (om.n_faces() - options.target_faces) / 2);
    decimater.set_observer(&observer);
    decimater.decimate_to_faces(0, options.target_faces);
    decimater.set_observer(nullptr);
    if (observer.stopped()) throw Cancelled("decimate: cancelled");
    om.garbage_collection();
  }
  report_progress(options.progress, "decimate", 1.0);

  // Garbage collection reorders vertices; the `source` property travels with them. The result numbers
  // the referenced survivors in input order.
  std::vector<std::uint8_t> used(mesh.positions.size(), 0);
  for (const auto fh : om.faces())
    for (const auto vh : om.fv_range(fh)) used[om.property(source, vh)] = 1;
  std::vector<std::uint32_t> renumber(mesh.positions.size(), 0);
  for (std::size_t v = 0; v < used.size(); ++v)
    if (used[v] != 0) {
      renumber[v] = static_cast<std::uint32_t>(result.source_vertex.size());
      result.source_vertex.push_back(static_cast<std::uint32_t>(v));
      result.mesh.positions.push_back(mesh.positions[v]);
    }
  result.mesh.faces.reserve(om.n_faces());
  for (const auto fh : om.faces()) {
    Face face{};
    std::size_t corner = 0;
    for (const auto vh : om.fv_range(fh)) face[corner++] = renumber[om.property(source, vh)];
    result.mesh.faces.push_back(face);
  }
  return result;
}


constexpr std::uint32_t kNone = 0xffffffffu;

}  // namespace

DecimatedPiece decimate_piece(MeshView brick, std::span<const std::uint32_t> ids, std::span<const std::uint8_t> locked,
                              std::size_t target_faces, double max_normal_turn_degrees) {
  DecimateOptions o;
  o.target_faces = std::max<std::size_t>(1, target_faces);
  o.locked = locked;
  o.max_normal_turn_degrees = max_normal_turn_degrees;
  check(brick, o);
  const QuietOpenMesh quiet;
  if (ids.size() != brick.positions.size())
    throw InvalidInput(fmt::format("decimate: {} ids for {} vertices", ids.size(), brick.positions.size()));
  DecimateResult r = decimate_one(brick, o);
  DecimatedPiece piece;
  piece.rejected_faces = r.rejected_faces;
  piece.faces = std::move(r.mesh.faces);
  piece.positions = std::move(r.mesh.positions);
  piece.ids.reserve(r.source_vertex.size());
  for (const std::uint32_t v : r.source_vertex) piece.ids.push_back(ids[v]);
  return piece;
}

DecimateResult finish_pieces(std::span<const DecimatedPiece> pieces, std::size_t id_count, const DecimateOptions& options) {
  // Weld by input id, in piece order.
  std::vector<std::uint32_t> welded_index(id_count, kNone);
  TriMesh welded;
  std::vector<std::uint32_t> welded_source;
  std::size_t rejected = 0;
  for (const DecimatedPiece& piece : pieces) {
    rejected += piece.rejected_faces;
    for (const Face& f : piece.faces) {
      Face face{};
      for (std::size_t c = 0; c < 3; ++c) {
        const std::uint32_t v = piece.ids.at(f[c]);
        if (v >= id_count) throw InvalidInput(fmt::format("decimate: piece vertex id {} of {}", v, id_count));
        if (welded_index[v] == kNone) {
          welded_index[v] = static_cast<std::uint32_t>(welded_source.size());
          welded_source.push_back(v);
          welded.positions.push_back(piece.positions.at(f[c]));
        }
        face[c] = welded_index[v];
      }
      welded.faces.push_back(face);
    }
  }
  if (welded.faces.empty()) throw InvalidInput("decimate: no faces in the pieces");
  if (!options.locked.empty() && options.locked.size() != id_count)
    throw InvalidInput(fmt::format("decimate: {} lock flags for {} ids", options.locked.size(), id_count));
  std::vector<std::uint8_t> locked;
  if (!options.locked.empty())
    for (const std::uint32_t v : welded_source) locked.push_back(options.locked[v]);
  DecimateOptions o = options;
  o.locked = locked;
  o.brick_of_face = {};
  if (options.progress)
    o.progress = [&options](std::string_view stage, double fraction) { return options.progress(stage, 0.8 + 0.2 * fraction); };
  check(welded, o);
  const QuietOpenMesh quiet;
  DecimateResult result = decimate_one(welded, o);
  result.rejected_faces += rejected;
  // Back to input ids, in input order (decimate_one numbers its vertices in welded order).
  std::vector<std::uint32_t> order(result.source_vertex.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<std::uint32_t>(i);
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    return welded_source[result.source_vertex[a]] < welded_source[result.source_vertex[b]];
  });
  std::vector<std::uint32_t> renumber(order.size());
  TriMesh sorted;
  std::vector<std::uint32_t> source;
  for (std::size_t i = 0; i < order.size(); ++i) {
    renumber[order[i]] = static_cast<std::uint32_t>(i);
    source.push_back(welded_source[result.source_vertex[order[i]]]);
    sorted.positions.push_back(result.mesh.positions[order[i]]);
  }
  for (Face f : result.mesh.faces) {
    for (std::uint32_t& v : f) v = renumber[v];
    sorted.faces.push_back(f);
  }
  result.mesh = std::move(sorted);
  result.source_vertex = std::move(source);
  return result;
}

std::vector<std::uint8_t> seam_vertices(MeshView mesh, std::span<const std::uint8_t> brick_of_face) {
  constexpr std::uint8_t kFree = 0xff, kSeam = 0xfe;
  std::vector<std::uint8_t> first(mesh.positions.size(), kFree);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f)
    for (const std::uint32_t v : mesh.faces[f])
      if (first[v] == kFree)
        first[v] = brick_of_face[f];
      else if (first[v] != brick_of_face[f])
        first[v] = kSeam;
  for (std::uint8_t& v : first) v = v == kSeam ? 1 : 0;
  return first;
}

namespace {

/// Bricks first (DecimateOptions::brick_of_face), then the welded whole.
DecimateResult decimate_bricks(MeshView mesh, const DecimateOptions& options) {
  std::size_t count = 0;
  for (const std::uint8_t b : options.brick_of_face) count = std::max<std::size_t>(count, std::size_t{b} + 1);
  std::vector<std::vector<std::uint32_t>> bricks(count);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) bricks[options.brick_of_face[f]].push_back(static_cast<std::uint32_t>(f));
  const std::vector<std::uint8_t> seam = seam_vertices(mesh, options.brick_of_face);
  std::vector<DecimatedPiece> pieces(count);
  std::atomic<std::size_t> done{0};
  std::atomic<bool> cancelled{false};
  tbb::parallel_for(std::size_t{0}, count, [&](std::size_t b) {
    if (cancelled.load(std::memory_order_relaxed) || bricks[b].empty()) return;
    // The brick's vertices in input order, so that every caller (one process, or ranks reading bricks from
    // a file) builds the same sub-mesh and gets the same piece.
    std::vector<std::uint32_t> ids;
    for (const std::uint32_t f : bricks[b])
      for (const std::uint32_t v : mesh.faces[f]) ids.push_back(v);
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    TriMesh sub;
    std::vector<std::uint8_t> locked(ids.size());
    for (std::size_t i = 0; i < ids.size(); ++i) {
      sub.positions.push_back(mesh.positions[ids[i]]);
      locked[i] = seam[ids[i]] != 0 || (!options.locked.empty() && options.locked[ids[i]] != 0) ? 1 : 0;
    }
    for (const std::uint32_t f : bricks[b]) {
      Face face{};
      for (std::size_t c = 0; c < 3; ++c)
        face[c] = static_cast<std::uint32_t>(std::lower_bound(ids.begin(), ids.end(), mesh.faces[f][c]) - ids.begin());
      sub.faces.push_back(face);
    }
    pieces[b] = decimate_piece(sub, ids, locked, brick_target(options.target_faces, bricks[b].size(), mesh.faces.size()),
                               options.max_normal_turn_degrees);
    const std::size_t finished = done.fetch_add(1) + 1;
    if (options.progress && !options.progress("decimate", 0.8 * static_cast<double>(finished) / static_cast<double>(count)))
      cancelled = true;
  });
  if (cancelled) throw Cancelled("decimate: cancelled");
  return finish_pieces(pieces, mesh.positions.size(), options);
}

}  // namespace

DecimateResult decimate_quadric(MeshView mesh, const DecimateOptions& options) {
  check(mesh, options);
  const QuietOpenMesh quiet;
  return !options.brick_of_face.empty() ? decimate_bricks(mesh, options) : decimate_one(mesh, options);
}

}  // namespace gimforge
