#pragma once
/// \file xdmf.h
/// XDMF 3 sidecars: a small XML file next to an archive that lets ParaView and VisIt open its geometry
/// images, spherical geometry images and batch stacks as structured grids (2DSMesh topology, XYZ points),
/// reading the float32 images straight from the HDF5 file. docs/archive.md, "Opening in ParaView".
///
/// - /gim/<name>: one grid of n × n points; `colors` become a node attribute.
/// - /spherical/<name>: one grid per face image of the domain layout (the cube's six faces are separate
///   grids, so no quad joins two faces); `mask` becomes a node attribute (undefined samples are NaN).
/// - /batch/<output> of an image method: a temporal collection, item k at time k, each a hyperslab of
///   `data` (N, 3, H, W) split into its X, Y and Z planes; `mask` when stored.
/// Relief maps are not structured grids and are not described (`gimforge reconstruct` gives a mesh).
/// Points are in the item's local frame: add its `frame_origin` attribute for world coordinates.
#include <filesystem>
#include <span>
#include <string>

#include "io/archive.h"

namespace gimforge::io {

/// The XDMF document for `archive`; HDF5 references name the file as `h5_reference` (the archive's file
/// name, relative to the sidecar's directory). Reads only attributes and shapes, and asks the chunk index
/// whether the file stores each item's data whole. Items whose layout is not what docs/archive.md describes,
/// or whose data is not all stored, are skipped (they are not renderable; readers report them), as are the
/// items `leave_out` names ("GROUP/NAME": those `gimforge ls` lists as unreadable). Names are XML-escaped.
[[nodiscard]] std::string archive_xdmf(const Archive& archive, const std::string& h5_reference,
                                       std::span<const std::string> leave_out = {});

/// The sidecar path of an archive: the archive's path with extension ".xmf" (".xmf" appended when the
/// archive's own extension is ".xmf", so the sidecar never replaces the archive).
[[nodiscard]] std::filesystem::path xdmf_sidecar_path(const std::filesystem::path& archive);

/// Writes the sidecar of the archive at `archive_path` (opened read-only) atomically next to it; returns
/// its path. With `grids`, sets it to whether the sidecar describes any grid (an archive of relief maps and
/// multi-chart images only gives an empty domain). `leave_out` as for archive_xdmf. Throws as Archive::open
/// and write_atomically do.
std::filesystem::path write_xdmf_sidecar(const std::filesystem::path& archive_path, bool* grids = nullptr,
                                         std::span<const std::string> leave_out = {});

}  // namespace gimforge::io
