#pragma once
/// \file reports.h
/// Turning kernel results into the JSON and text that the CLI prints (docs/cli.md describes both).
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "jobs/load_mesh.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/topology.h"

namespace gimforge::jobs {

/// The spacing of float32 values at the mesh's largest coordinate, in its units, when the file stores its
/// coordinates as float32 (`float32_storage`: io::ReadInfo::float32_coordinates; a double or text file that
/// holds float32-exact values, integers of a 1 m grid for instance, has lost nothing) and that spacing
/// exceeds io::kFloat32Tolerance of the bounding-box diagonal (the file has lost detail before gimforge reads
/// it: load_mesh's warning, info's `float32_resolution`); nullopt otherwise.
[[nodiscard]] std::optional<double> float32_resolution(const TriMesh& mesh, bool float32_storage);

/// `gimforge info --json`: file facts, topology (keys vertices faces components boundary_loops genus closed
/// manifold bbox_diagonal, ...), defects found and repairs made.
[[nodiscard]] nlohmann::json info_json(const LoadedMesh& mesh, const TopologyReport& topology);
/// Human-readable form of the same.
[[nodiscard]] std::string info_text(const LoadedMesh& mesh, const TopologyReport& topology);

/// `gimforge metrics --json`, exactly {"diag", "ab": {"max","mean","rms"}, "ba": {...}, "max", "rms", "psnr"}.
/// psnr is null when rms is 0 (identical surfaces: infinite PSNR).
[[nodiscard]] nlohmann::json metrics_json(const HausdorffResult& result);
/// Human-readable form of the same, naming the two files.
[[nodiscard]] std::string metrics_text(const HausdorffResult& result, const std::string& a, const std::string& b);

/// `gimforge validate --json`: defects with kind, severity, count and message.
[[nodiscard]] nlohmann::json validation_json(const LoadedMesh& mesh);

}  // namespace gimforge::jobs
