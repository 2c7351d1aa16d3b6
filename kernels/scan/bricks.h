#pragma once
/// \file bricks.h
/// Spatial bricks of (nearly) equal triangle count for splitting a huge scan across ranks (issue #17,
/// item 1; ../shared/notes/huge-scans.md: distributed Poisson reconstruction balances slabs by point
/// count). A first pass over the faces fills a coarse histogram of their centroids (per rank, then summed);
/// the master cuts it into bricks with k-d splits, each split at the histogram plane that divides the count
/// in proportion to the bricks on either side. A face belongs to the brick that holds its centroid, so
/// every face has exactly one owner whatever the number of ranks.
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "kernels/core/mesh.h"

namespace gimforge {

/// Counts of points in a regular grid over a box (cells are half-open; points on the box's far faces go to
/// the last cell; points outside are clamped into the border cells).
class CentroidHistogram {
 public:
  /// Throws InvalidInput for an empty or non-finite box or a zero dimension or more than 2^26 cells.
  CentroidHistogram(const BoundingBox& box, std::array<std::uint32_t, 3> dims);

  /// The grid cell of `p` (clamped). Non-finite coordinates go to cell 0 along that axis.
  [[nodiscard]] std::array<std::uint32_t, 3> cell_of(const Vec3& p) const;
  void add(const Vec3& p, std::uint64_t count = 1);
  /// The centroid of each face of `mesh` (a block of a streamed mesh: faces index `positions`).
  void add_face_centroids(std::span<const Vec3> positions, std::span<const Face> faces);

  [[nodiscard]] const BoundingBox& box() const { return box_; }
  [[nodiscard]] const std::array<std::uint32_t, 3>& dims() const { return dims_; }
  /// Counts, x fastest (for summing across ranks: element-wise).
  [[nodiscard]] std::vector<std::uint64_t>& counts() { return counts_; }
  [[nodiscard]] const std::vector<std::uint64_t>& counts() const { return counts_; }
  [[nodiscard]] std::uint64_t total() const;

 private:
  BoundingBox box_;
  std::array<std::uint32_t, 3> dims_;
  std::vector<std::uint64_t> counts_;
};

/// Bricks as boxes of histogram cells: brick b covers cells [lo[b], hi[b]) on each axis.
struct BrickPartition {
  BoundingBox box;                       ///< the histogram's box
  std::array<std::uint32_t, 3> dims{};   ///< the histogram's cells per axis
  std::vector<std::array<std::uint32_t, 3>> lo;
  std::vector<std::array<std::uint32_t, 3>> hi;
  std::vector<std::uint64_t> count;      ///< histogram count of each brick
  /// The k-d tree: node 0 is the root; a leaf holds its brick, an inner node sends cells below `plane`
  /// on `axis` to `left`, the others to `right`.
  struct Node {
    int axis{-1};              ///< −1: a leaf
    std::uint32_t plane{0};
    std::uint32_t left{0};     ///< node index (inner) or brick index (leaf)
    std::uint32_t right{0};
  };
  std::vector<Node> nodes;

  [[nodiscard]] std::size_t size() const { return lo.size(); }
  /// The brick holding point `p` (clamped into the box like CentroidHistogram::cell_of).
  [[nodiscard]] std::size_t brick_of(const Vec3& p) const;
  /// The spatial box of brick b (its cells; the outer bricks end at the box).
  [[nodiscard]] BoundingBox bounds(std::size_t b) const;
};

/// Cuts the histogram into `bricks` bricks by recursive k-d splits: a node for k bricks splits along its
/// longest axis (in space) that has more than one cell, at the cell plane where the count before it comes
/// closest to ⌊k/2⌋/k of the node's count; the halves get ⌊k/2⌋ and k − ⌊k/2⌋ bricks. A node one cell
/// wide on every axis cannot split: its extra bricks stay empty (the histogram is too coarse for that many
/// bricks). Deterministic. Throws InvalidInput for bricks == 0.
[[nodiscard]] BrickPartition partition_bricks(const CentroidHistogram& histogram, std::size_t bricks);

}  // namespace gimforge
