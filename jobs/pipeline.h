#pragma once
/// \file pipeline.h
/// The one conversion pipeline: a loaded mesh and a method's options in, the method's typed result, its
/// fidelity against the input and every statistic out; then either an archive group (`convert`) or a batch
/// item (`batch`). Both commands record the same numbers for the same conversion, because both take them
/// from Conversion::numbers.
#include <chrono>
#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "io/archive.h"
#include "io/batch_shard.h"
#include "io/batch_types.h"
#include "jobs/method.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"
#include "kernels/gim/gim_convert.h"
#include "kernels/relief/relief_map.h"
#include "kernels/sphere/sphere_convert.h"

namespace gimforge::jobs {

/// The fidelity report: the papers' symmetric RMS Hausdorff distance between the input and the result's
/// reconstruction, and its PSNR.
struct FidelityOptions {
  bool enabled{true};              ///< false (`--no-metric`): no report, no psnr / hausdorff_* numbers
  std::size_t samples{1'000'000};  ///< area samples per direction
};

/// What to convert a mesh to.
struct ConversionRequest {
  std::string source{};  ///< the mesh's path: recorded, and prefixed to errors about the mesh
  MethodOptions method{};
  FidelityOptions fidelity{};
  /// Sphere only: resample this stored sphere map (one unit vector per vertex, io::SphereParametrization)
  /// instead of optimizing one.
  std::optional<std::vector<Vec3>> sphere_map{};
  /// Progress and cancellation of every stage (kernel stages, then "distance A->B", "distance B->A").
  ProgressCallback progress{};
};

/// The result of one conversion.
struct Conversion {
  Method method{Method::Gim};
  std::string source;                  ///< ConversionRequest::source
  std::optional<GimResult> gim;        ///< Method::Gim
  std::optional<SphereResult> sphere;  ///< Method::Sphere
  std::optional<ReliefMap> relief;     ///< Method::Relief
  std::optional<HausdorffResult> fidelity;  ///< absent when FidelityOptions::enabled is false
  std::size_t input_vertices{0};
  std::size_t input_faces{0};
  double seconds_construct{0.0};  ///< the method's kernel
  double seconds_metric{0.0};     ///< the fidelity report (its reconstruction included)
  double seconds_total{0.0};      ///< both, plus the work in between
  /// Every statistic of the conversion under its archive name: the method's own (e.g. gim cut_paths,
  /// stretch_efficiency; sphere map_efficiency, domain_efficiency; relief occlusion_ratio, storage_bytes),
  /// input_faces, the fidelity (psnr, hausdorff_rms, hausdorff_max, bbox_diagonal) and the timings
  /// (seconds_construct, seconds_metric, seconds_total and the method's stage timings). `convert` stores
  /// them as the attributes of the representation group, `batch` as the item's metrics.
  std::map<std::string, double> numbers;
};

/// Runs the method on `mesh` (loaded under load_policy(request.method.method)) and measures the result.
/// Throws InvalidInput for options the method refuses (MethodOptions::check), the kernels' errors
/// (TopologyError, InvalidInput, ...), and Cancelled when the progress callback stops it; errors about the
/// mesh start with request.source.
[[nodiscard]] Conversion convert_mesh(const EmbreeDevice& device, const TriMesh& mesh, const ConversionRequest& request);

/// Writes `conversion` as representation `name` of `archive` (/gim/<name>, /spherical/<name> or
/// /relief/<name>, docs/archive.md) with its source and Conversion::numbers as its record.
/// Throws as the io writers do (invalid name, taken name, HDF5 failure).
void write_conversion(io::Archive& archive, const std::string& name, const Conversion& conversion);

/// What a batch stores for one converted item: the channel-first image and mask of gim and sphere
/// (stacked into (N, C, H, W) by the merge), or, for relief maps, a `representation` writer that fills the
/// item's group with the layout of /relief/<name>; Conversion::numbers become the item's metrics.
struct BatchItem {
  io::ItemArrays arrays;
  io::RepresentationWriter representation;  ///< empty for image methods
};
/// The item refers to `conversion` (the relief writer reads its map): keep the conversion alive until the
/// shard is written. A temporary cannot be passed.
[[nodiscard]] BatchItem batch_item(const Conversion& conversion);
BatchItem batch_item(Conversion&&) = delete;

/// The archive's `creation_parameters` for a `convert` run: the method's options and the metric settings.
[[nodiscard]] nlohmann::json creation_parameters(const ConversionRequest& request);

}  // namespace gimforge::jobs
