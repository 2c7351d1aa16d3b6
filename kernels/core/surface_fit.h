#pragma once
/// \file surface_fit.h
/// Geometry-image optimization (Sander et al. 2003, §4.6, extending the mesh optimization of Hoppe et al.
/// 1993): moves the vertices of a remesh whose connectivity follows from its positions (a regular grid whose
/// quads split along their shorter diagonal) to fit a reference surface. The energy is
///   E(x) = (1/N) Σ_i |r_i − Π_M(x)(r_i)|²  +  w · L̄² · (1/n_e) Σ_e |θ_e|^p   (p = 4 in the paper)
/// with r_i N dense area samples of the reference surface, Π_M their exact closest points on the remesh
/// M(x) (Embree), θ_e the dihedral angle of an edge with exactly two faces (0 where they are coplanar; edges
/// with one or more than two faces, or with a sliver face over them, contribute nothing), n_e the number of
/// such edges and L̄² the mean squared edge length, both of the input remesh and held fixed during the fit (so that shrinking the mesh
/// does not lower the smoothness term). Both terms are then squared lengths and averages: w is free of the
/// mesh's scale, vertex count and sample count, and w = 1e-3 makes a uniform bend of 0.3 rad per edge cost
/// as much as an rms fit error of 0.3% of an edge: little pull on a remesh sampled on the surface (the
/// pipeline's case), but too little to stop a remesh that starts edges away from the surface from folding
/// while it travels (w ≈ 0.1 does, on smooth surfaces). Minimized by nonlinear conjugate gradients
/// (Polak–Ribière+, restarted every 20 iterations, when the direction is not downhill and when it stalls) and
/// a backtracking (Armijo) line search with quadratic interpolation and expansion; the first trial step of
/// each line search moves no vertex farther than the last accepted step did (10% of the mean edge length at
/// first, never more than one). The triangulation is re-chosen from the positions before every energy
/// evaluation, as the paper says, which makes E jump where a diagonal flips: when a trial step fails on a
/// changed triangulation, the vertices of the changed faces are held for that step, so that one quad at its
/// flipping point cannot stall the rest. The gradient is that of the current triangulation with the closest
/// points held fixed (Hoppe 1993). Shared by every image method (gim, sphere, mcgim): vertices that several
/// samples share (cut mates, zippered samples) are one vertex here, so they move together and watertightness
/// is kept.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "kernels/core/embree_device.h"
#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"

namespace gimforge {

/// The remesh's triangles for the given vertex positions (e.g. each grid quad split along its shorter
/// diagonal). Faces that repeat a vertex are ignored by the fit.
using Triangulator = std::function<std::vector<Face>(std::span<const Vec3> positions)>;

struct SurfaceFitOptions {
  std::size_t reference_samples{200'000};  ///< N: area samples of the reference (at least 4 per vertex are used)
  double smoothness{1e-3};                 ///< w: weight of the dihedral term
  int exponent{4};                         ///< p of the L^p norm of the dihedral angles (paper: 4), in [1, 16]
  int iterations{60};                      ///< conjugate-gradient iterations (a bound, >= 0)
  double tolerance{1e-7};                  ///< stop when an iteration lowers E by less than this fraction
  std::uint64_t seed{0x5eed};              ///< of the reference samples
  ProgressCallback progress{};             ///< stage "optimize"
};

struct SurfaceFitResult {
  std::vector<Vec3> positions;   ///< the fitted vertices (the input when nothing improved)
  double energy_before{0.0};     ///< E at the input
  double energy_after{0.0};      ///< E at the result (≤ energy_before)
  double fit_before{0.0};        ///< the fit term alone: Σ squared distances / number of samples
  double fit_after{0.0};
  int iterations{0};
  double seconds{0.0};
};

/// What a fit fits to: a reference mesh, sampled by the fit (sample_surface: max(reference_samples, 4 per
/// remesh vertex) points with the options' seed), or area samples drawn beforehand — the same samples of a
/// surface too large for one process, drawn by ranks each on their slice of its faces (jobs/brick_metrics.h),
/// or of the full surface behind a proxy that the remesh was made from (jobs/proxy.h).
struct FitReference {
  MeshView mesh{};
  std::span<const Vec3> points{};  ///< when not empty: the samples, and `mesh` is not used

  FitReference(MeshView m) : mesh(m) {}        // NOLINT: implicit by design, as MeshView's
  FitReference(const TriMesh& m) : mesh(m) {}  // NOLINT
  [[nodiscard]] static FitReference samples(std::span<const Vec3> p) {
    FitReference r{MeshView{}};
    r.points = p;
    return r;
  }
};

/// Fits `positions` (the remesh's vertices; `locked[v] != 0` keeps v in place, `locked` may be empty) to
/// `reference`. Never returns an energy above the input's. `triangulate` is called with the current positions
/// before every energy evaluation. Throws InvalidInput (empty or non-finite input, size mismatch, a
/// triangulation indexing out of range or without a face of three distinct vertices, an option out of range,
/// a reference without area or a non-finite reference sample), LibraryError (Embree), Cancelled via progress.
[[nodiscard]] SurfaceFitResult fit_surface(const EmbreeDevice& device, const FitReference& reference, std::vector<Vec3> positions,
                                           const Triangulator& triangulate, std::span<const char> locked,
                                           const SurfaceFitOptions& options = {});

}  // namespace gimforge
