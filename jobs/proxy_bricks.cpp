#include "jobs/proxy_bricks.h"

#include <algorithm>

#include "kernels/core/errors.h"

namespace gimforge::jobs {

ProxyBricks assign_proxy_bricks(const ScannedMesh& scanned, const BrickPartition& partition, const Vec3& origin,
                                const std::function<void(std::uint8_t, const Face&)>& keep) {
  const io::PlyTriangleFile& file = *scanned.file;
  ProxyBricks out;
  out.bricks = partition.size();
  out.brick_faces.assign(out.bricks, 0);
  out.brick_of_vertex.assign(static_cast<std::size_t>(file.vertices()), kNoBrick);
  file.read_vertices(0, file.vertices(), [&](std::uint64_t at, std::span<const Vec3> p) {
    for (std::size_t i = 0; i < p.size(); ++i)
      if (scanned.referenced[at + i]) out.brick_of_vertex[at + i] = static_cast<std::uint8_t>(partition.brick_of(p[i] - origin));
  });
  // A vertex used by faces of two bricks is a seam (kernels/scan/decimate.h seam_vertices).
  out.seam.assign(out.brick_of_vertex.size(), kNoBrick);
  file.read_faces(0, file.faces(), [&](std::uint64_t at, std::span<const Face> faces) {
    for (std::size_t i = 0; i < faces.size(); ++i) {
      const Face& t = faces[i];
      if (has_repeated_index(t) || (!scanned.dropped.empty() && scanned.is_dropped(at + i))) continue;
      const std::uint8_t b = out.brick_of_vertex[t[0]];
      for (const std::uint32_t v : t)
        if (out.seam[v] == kNoBrick)
          out.seam[v] = b;
        else if (out.seam[v] != b)
          out.seam[v] = kSeamVertex;
      ++out.brick_faces[b];
      if (keep) keep(b, t);
    }
  });
  return out;
}

DecimatedPiece decimate_brick(const io::PlyTriangleFile& file, const std::vector<Face>& faces, const ProxyBricks& bricks,
                              const Vec3& origin, std::size_t target, std::uint64_t scan_faces) {
  std::vector<std::uint32_t> ids;
  ids.reserve(3 * faces.size());
  for (const Face& t : faces) ids.insert(ids.end(), t.begin(), t.end());
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  TriMesh sub;
  sub.positions = file.read_positions(ids);
  for (Vec3& p : sub.positions) p -= origin;
  std::vector<std::uint8_t> locked(ids.size());
  for (std::size_t i = 0; i < ids.size(); ++i) locked[i] = bricks.seam[ids[i]] == kSeamVertex ? 1 : 0;
  sub.faces.reserve(faces.size());
  for (const Face& t : faces) {
    Face face{};
    for (std::size_t c = 0; c < 3; ++c)
      face[c] = static_cast<std::uint32_t>(std::lower_bound(ids.begin(), ids.end(), t[c]) - ids.begin());
    sub.faces.push_back(face);
  }
  return decimate_piece(sub, ids, locked, brick_target(target, faces.size(), static_cast<std::size_t>(scan_faces)));
}

TriMesh finish_proxy(std::vector<DecimatedPiece> pieces, std::uint64_t file_vertices, std::size_t target,
                     std::size_t bricks, const ProgressCallback& progress, std::map<std::string, double>& numbers) {
  DecimateOptions options;
  options.target_faces = target;
  options.progress = progress;
  DecimateResult r = finish_pieces(pieces, static_cast<std::size_t>(file_vertices), options);
  if (r.mesh.faces.empty()) throw InvalidInput("the proxy has no face left");
  numbers["proxy_faces"] = static_cast<double>(r.mesh.num_faces());
  numbers["proxy_vertices"] = static_cast<double>(r.mesh.num_vertices());
  numbers["proxy_rejected_faces"] = static_cast<double>(r.rejected_faces);
  numbers["proxy_bricks"] = static_cast<double>(bricks);
  return std::move(r.mesh);
}

void put_piece(Bytes& out, std::uint64_t brick, const DecimatedPiece& piece) {
  out.put(std::vector<std::uint64_t>{brick, piece.rejected_faces});
  out.put(piece.ids);
  out.put(piece.positions);
  out.put(piece.faces);
}

std::pair<std::uint64_t, DecimatedPiece> get_piece(Bytes& in) {
  const std::vector<std::uint64_t> head = in.get<std::uint64_t>();
  if (head.size() != 2) in.short_of("a piece's header");
  DecimatedPiece piece;
  piece.rejected_faces = head[1];
  piece.ids = in.get<std::uint32_t>();
  piece.positions = in.get<Vec3>();
  piece.faces = in.get<Face>();
  if (piece.positions.size() != piece.ids.size())
    throw FormatError(in.what + ": a piece has " + std::to_string(piece.ids.size()) + " ids for " +
                      std::to_string(piece.positions.size()) + " positions");
  for (std::size_t i = 1; i < piece.ids.size(); ++i)
    if (piece.ids[i] <= piece.ids[i - 1]) throw FormatError(in.what + ": a piece's vertex ids are out of order");
  for (const Face& f : piece.faces)
    for (const std::uint32_t v : f)
      if (v >= piece.ids.size()) throw FormatError(in.what + ": a piece's face names a vertex it does not have");
  for (const Vec3& p : piece.positions)
    if (!p.allFinite()) throw FormatError(in.what + ": a piece has a non-finite position");
  return {head[0], std::move(piece)};
}

}  // namespace gimforge::jobs
