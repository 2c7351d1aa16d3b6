#pragma once
/// \file chartify.h
/// Chartification of multi-chart geometry images (Sander, Wood, Gortler, Snyder, Hoppe 2003, §4.1): a
/// Lloyd–Max style clustering of the faces on the dual graph. Phase 1 grows every chart from its seed face at
/// once by a Dijkstra search with edge cost (λ − N_C·N_F′)·|P_F′ − P_F| (N_C the running, area-weighted
/// average normal of the chart, P the face centroids); phase 2 moves each seed to the chart's "most interior"
/// face (the last face reached by a Dijkstra search inward from the chart boundaries, cost |P_F′ − P_F|).
/// Bootstrapping adds one seed per round (the last face phase 1 assigned) until the requested count; then
/// the phases repeat until the seeds no longer change, a cycle of seed sets is detected, or (ours) a growth
/// from moved seeds leaves faces that no chart can take after three rounds already did (each such round
/// adds seeds), which keeps the round before. During growth
/// every chart stays a topological disk (no annulus, no closed chart); a face that no chart can take makes
/// the first face that failed the rule a new seed, as does a connected component without a seed (one seed
/// per connected region of faces left over, all added before the growth reruns).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"

namespace gimforge {

struct ChartifyOptions {
  std::uint32_t charts{16};   ///< requested charts (≥ 1); more are added where the disk rule or components need them
  double lambda{1.0};         ///< λ of the growth cost (paper: 1)
  int max_iterations{200};    ///< rounds of phases 1 + 2 after bootstrapping (a bound; convergence or a cycle ends sooner)
  std::uint64_t seed{1};      ///< chooses the first seed face (reproducible)
  ProgressCallback progress{};  ///< stage "chartify"
};

struct Chartification {
  std::vector<std::uint32_t> face_chart;  ///< the chart of every face, 0 .. num_charts − 1
  std::vector<std::uint32_t> seeds;       ///< the seed face of every chart (the face chart c grew from)
  std::uint32_t num_charts{0};
  int bootstrap_rounds{0};                ///< rounds that added a seed toward the requested count
  int iterations{0};                      ///< rounds of phases 1 + 2 after bootstrapping
  bool converged{false};                  ///< the seeds of the last round equal those of the round before
  bool cycle{false};                      ///< stopped because a set of seeds repeated an earlier round's
  bool fragmenting{false};                ///< stopped because a fourth Lloyd round's growth left faces no chart
                                          ///< could take (it would need more seeds): the round before is kept
  std::uint32_t extra_seeds{0};           ///< seeds added beyond the request (disk rule, components):
                                          ///< num_charts − min(charts, faces); a disk-rule seed added while
                                          ///< bootstrapping counts toward the request instead
};

/// Partitions the faces of `mesh` into charts that are topological disks (connected, one boundary loop).
/// Preconditions: an edge-manifold, consistently oriented mesh without degenerate (repeated-index) faces and
/// at least one face (throws InvalidInput otherwise; TopologyError for a non-manifold edge or two faces that
/// disagree on the orientation of their edge; InvalidInput for a non-finite coordinate, charts = 0, a negative
/// or non-finite lambda, max_iterations < 0). Throws Cancelled via the progress callback. Deterministic: the
/// same mesh and options give the same result. Cost O(F log F) per round.
[[nodiscard]] Chartification chartify(MeshView mesh, const ChartifyOptions& options = {});

/// True when the faces `faces` of `mesh` form one topological disk: edge-connected, every vertex's faces
/// in the set one fan, Euler characteristic V − E + F = 1 and at least one boundary edge. For tests and
/// checks of the chartification. Repeated indices in `faces` count once; an empty set or a face with a repeated
/// vertex index is no disk. Throws InvalidInput for a face or vertex index out of range.
[[nodiscard]] bool is_topological_disk(MeshView mesh, const std::vector<std::uint32_t>& faces);

}  // namespace gimforge
