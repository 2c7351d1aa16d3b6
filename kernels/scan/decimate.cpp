/// \file decimate.cpp
/// OpenMesh's Decimater with the quadric module (priority) and the normal-flipping module (binary). The
/// only translation unit that includes OpenMesh: its templates are instantiated once, here.
#include "kernels/scan/decimate.h"

#include <algorithm>
#include <atomic>
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
  if (!(options.max_normal_turn_degrees > 0.0 && options.max_normal_turn_degrees <= 180.0))
    throw InvalidInput(fmt::format("decimate: the normal bound {} degrees is not in (0, 180]", options.max_normal_turn_degrees));
  for (const Face& f : mesh.faces)
    for (const std::uint32_t v : f)
      if (v >= mesh.positions.size())
        throw InvalidInput(fmt::format("decimate: a face names vertex {} of {}", v, mesh.positions.size()));
}

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


/// The faces split into `count` groups of (nearly) equal size by recursive median cuts of their centroids
/// along the longest axis of each group's box: spatially compact bricks.
std::vector<std::vector<std::uint32_t>> face_bricks(MeshView mesh, std::size_t count) {
  std::vector<Vec3> centroid(mesh.faces.size());
  for (std::size_t f = 0; f < centroid.size(); ++f) {
    const Face& face = mesh.faces[f];
    centroid[f] = (mesh.positions[face[0]] + mesh.positions[face[1]] + mesh.positions[face[2]]) / 3.0;
  }
  std::vector<std::uint32_t> order(mesh.faces.size());
  for (std::size_t f = 0; f < order.size(); ++f) order[f] = static_cast<std::uint32_t>(f);
  std::vector<std::vector<std::uint32_t>> out;
  // split(first, last, k): the faces order[first, last) into k bricks.
  const auto split = [&](auto&& self, std::size_t first, std::size_t last, std::size_t k) -> void {
    if (k <= 1 || last - first < 2) {
      out.emplace_back(order.begin() + static_cast<std::ptrdiff_t>(first), order.begin() + static_cast<std::ptrdiff_t>(last));
      std::sort(out.back().begin(), out.back().end());
      return;
    }
    BoundingBox box;
    for (std::size_t i = first; i < last; ++i) box.extend(centroid[order[i]]);
    Eigen::Index axis = 0;
    (box.max - box.min).maxCoeff(&axis);
    const std::size_t left = k / 2;
    const std::size_t mid = first + (last - first) * left / k;
    // Ties broken by face index, so the bricks do not depend on the sort's internals.
    std::nth_element(order.begin() + static_cast<std::ptrdiff_t>(first), order.begin() + static_cast<std::ptrdiff_t>(mid),
                     order.begin() + static_cast<std::ptrdiff_t>(last), [&](std::uint32_t a, std::uint32_t b) {
                       const double ca = centroid[a][axis], cb = centroid[b][axis];
                       return ca < cb || (ca == cb && a < b);
                     });
    self(self, first, mid, left);
    self(self, mid, last, k - left);
  };
  split(split, 0, order.size(), count);
  return out;
}

/// Bricks first: every brick decimated on its own (in parallel) to twice its share of the target, with the
/// vertices it shares with other bricks locked, then the welded result decimated as a whole.
DecimateResult decimate_bricks(MeshView mesh, const DecimateOptions& options) {
  const std::vector<std::vector<std::uint32_t>> bricks = face_bricks(mesh, options.bricks);
  // A vertex used by two bricks is a seam vertex: locked in the first pass.
  constexpr std::uint32_t kNone = 0xffffffffu, kSeam = 0xfffffffeu;
  std::vector<std::uint32_t> brick_of(mesh.positions.size(), kNone);
  for (std::uint32_t b = 0; b < bricks.size(); ++b)
    for (const std::uint32_t f : bricks[b])
      for (const std::uint32_t v : mesh.faces[f])
        if (brick_of[v] == kNone)
          brick_of[v] = b;
        else if (brick_of[v] != b)
          brick_of[v] = kSeam;
  std::vector<DecimateResult> pieces(bricks.size());
  std::vector<std::vector<std::uint32_t>> piece_vertices(bricks.size());  // local -> input vertex
  std::atomic<std::size_t> done{0};
  std::atomic<bool> cancelled{false};
  tbb::parallel_for(std::size_t{0}, bricks.size(), [&](std::size_t b) {
    if (cancelled.load(std::memory_order_relaxed)) return;
    const std::vector<std::uint32_t>& faces = bricks[b];
    std::unordered_map<std::uint32_t, std::uint32_t> local;
    local.reserve(faces.size());
    TriMesh sub;
    std::vector<std::uint8_t> locked;
    std::vector<std::uint32_t>& global = piece_vertices[b];
    sub.faces.reserve(faces.size());
    for (const std::uint32_t f : faces) {
      Face face{};
      for (std::size_t c = 0; c < 3; ++c) {
        const std::uint32_t v = mesh.faces[f][c];
        const auto [it, added] = local.try_emplace(v, static_cast<std::uint32_t>(global.size()));
        if (added) {
          global.push_back(v);
          sub.positions.push_back(mesh.positions[v]);
          locked.push_back(brick_of[v] == kSeam || (!options.locked.empty() && options.locked[v] != 0) ? 1 : 0);
        }
        face[c] = it->second;
      }
      sub.faces.push_back(face);
    }
    DecimateOptions o;
    o.target_faces = std::max<std::size_t>(1, 2 * options.target_faces * faces.size() / mesh.faces.size());
    o.locked = locked;
    o.max_normal_turn_degrees = options.max_normal_turn_degrees;
    pieces[b] = decimate_one(sub, o);
    const std::size_t finished = done.fetch_add(1) + 1;
    if (options.progress && !options.progress("decimate", 0.8 * static_cast<double>(finished) / static_cast<double>(bricks.size())))
      cancelled = true;
  });
  if (cancelled) throw Cancelled("decimate: cancelled");

  // Weld the pieces by input vertex and decimate the whole.
  std::vector<std::uint32_t> welded_index(mesh.positions.size(), kNone);
  TriMesh welded;
  std::vector<std::uint32_t> welded_source;
  std::size_t rejected = 0;
  for (std::size_t b = 0; b < pieces.size(); ++b) {
    rejected += pieces[b].rejected_faces;
    for (const Face& f : pieces[b].mesh.faces) {
      Face face{};
      for (std::size_t c = 0; c < 3; ++c) {
        const std::uint32_t v = piece_vertices[b][pieces[b].source_vertex[f[c]]];
        if (welded_index[v] == kNone) {
          welded_index[v] = static_cast<std::uint32_t>(welded_source.size());
          welded_source.push_back(v);
          welded.positions.push_back(mesh.positions[v]);
        }
        face[c] = welded_index[v];
      }
      welded.faces.push_back(face);
    }
  }
  std::vector<std::uint8_t> locked;
  if (!options.locked.empty())
    for (const std::uint32_t v : welded_source) locked.push_back(options.locked[v]);
  DecimateOptions o = options;
  o.locked = locked;
  if (options.progress)
    o.progress = [&options](std::string_view stage, double fraction) { return options.progress(stage, 0.8 + 0.2 * fraction); };
  DecimateResult result = decimate_one(welded, o);
  result.rejected_faces += rejected;
  // Back to input indices, in input order (decimate_one numbers its vertices in welded order).
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

}  // namespace

DecimateResult decimate_quadric(MeshView mesh, const DecimateOptions& options) {
  check(mesh, options);
  // OpenMesh reports a face it cannot insert on its error stream; the count says it to the caller instead.
  ::omerr().disable();
  try {
    DecimateResult r = options.bricks > 1 && mesh.faces.size() > 4 * options.target_faces
                           ? decimate_bricks(mesh, options)
                           : decimate_one(mesh, options);
    ::omerr().enable();
    return r;
  } catch (...) {
    ::omerr().enable();
    throw;
  }
}

}  // namespace gimforge
