#pragma once
/// \file procedural.h
/// Procedural meshes with known geometry and topology, for tests, benchmarks and examples.
#include <cstddef>

#include "kernels/core/mesh.h"

namespace gimforge {

/// Icosphere of the given radius centred at the origin: an icosahedron whose faces are split 4-to-1
/// `subdivisions` times, vertices pushed to the sphere. 20·4^s faces, closed, genus 0, outward normals.
[[nodiscard]] TriMesh make_icosphere(double radius = 1.0, int subdivisions = 3);

/// Torus around the z axis: major radius R, minor radius r, nu × nv quads split into triangles.
/// Closed, genus 1. Preconditions: R > r > 0, nu, nv >= 3.
[[nodiscard]] TriMesh make_torus(double major_radius, double minor_radius, std::size_t nu, std::size_t nv);

/// Flat square grid [0,size]² in the z = 0 plane with nx × ny quads split into triangles: a disk
/// (one boundary loop), counter-clockwise seen from +z.
[[nodiscard]] TriMesh make_grid(std::size_t nx, std::size_t ny, double size = 1.0);

/// Closed surface of genus `genus` (>= 0): the boundary of a one-cell-thick slab of (2g+1)s × 3s unit cells
/// with g holes of s × s cells punched through it in a row; quads split into triangles, oriented outwards.
/// Preconditions: genus >= 0, s >= 1.
[[nodiscard]] TriMesh make_slab_with_holes(int genus, int s = 1);

/// Concatenates meshes (their faces reindexed); the result has one component per closed input.
[[nodiscard]] TriMesh concatenate(const TriMesh& a, const TriMesh& b);

}  // namespace gimforge
