#pragma once
/// \file pipeline.h
/// The one conversion pipeline: a loaded mesh and a method's options in, the method's typed result, its
/// fidelity against the input and every statistic out; then either an archive group (`convert`) or a batch
/// item (`batch`). Both commands record the same numbers for the same conversion, because both take them
/// from Conversion::numbers. Every kernel runs in the mesh's local frame (jobs/load_mesh.h): results are
/// stored relative to its origin, which is stored beside them (`frame_origin`) and added back on reading
/// (item_origin). Every item records its provenance: the gimforge version and the command line.
#include <chrono>
#include <cstddef>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "io/archive.h"
#include "io/batch_shard.h"
#include "io/batch_types.h"
#include "io/mesh_io.h"
#include "jobs/method.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/hausdorff.h"
#include "kernels/core/mesh.h"
#include "kernels/core/progress.h"
#include "kernels/gim/gim_convert.h"
#include "kernels/mcgim/mcgim_convert.h"
#include "kernels/relief/relief_map.h"
#include "kernels/sphere/sphere_convert.h"

namespace gimforge::jobs {

/// The fidelity report: the papers' symmetric RMS Hausdorff distance between the input and the result's
/// reconstruction, and its PSNR.
struct FidelityOptions {
  bool enabled{true};              ///< false (`--no-metric`): no report, no psnr / hausdorff_* numbers
  std::size_t samples{1'000'000};  ///< area samples per direction
};

/// Makes the proxy of `local` (the input in its local frame at `origin`) with at most `target` faces, adding
/// the proxy numbers (jobs/proxy.h make_proxy) to `numbers`; `progress` as the request's (cancellation).
using ProxyMaker = std::function<TriMesh(const TriMesh& local, const Vec3& origin, std::size_t target,
                                         const ProgressCallback& progress, std::map<std::string, double>& numbers)>;

/// What to convert a mesh to.
struct ConversionRequest {
  std::string source{};  ///< the mesh's path: recorded, and prefixed to errors about the mesh
  MethodOptions method{};
  FidelityOptions fidelity{};
  /// Sphere only: resample this stored sphere map (one unit vector per vertex, io::SphereParametrization)
  /// instead of optimizing one.
  std::optional<std::vector<Vec3>> sphere_map{};
  /// Adaptive gim or sphere with a region of interest (method.roi): resolved against the loaded mesh
  /// (jobs/roi.h resolve_roi);
  /// its vertex flags are per vertex of the mesh given to convert_mesh.
  RoiSource roi{};
  /// How the proxy of a huge input is made; empty: make_proxy of the mesh. A batch's brick tasks give the
  /// pieces they decimated (jobs/brick_tasks.h).
  ProxyMaker proxy_maker{};
  /// Progress and cancellation of every stage (kernel stages, then "distance A->B", "distance B->A").
  ProgressCallback progress{};
  /// The command line recorded as the item's `command_line`; empty: the process's (set_command_line).
  std::string command_line{};
};

/// The result of one conversion.
struct Conversion {
  Method method{Method::Gim};
  std::string source;                  ///< ConversionRequest::source
  /// The origin of the local frame the kernels ran in (local_frame_origin of the input): every position
  /// of the results (gim and sphere images, the relief map's origin) is relative to it.
  Vec3 origin{Vec3::Zero()};
  std::string command_line;            ///< ConversionRequest::command_line, or the process's
  std::string created;                 ///< when the conversion finished, ISO-8601 UTC
  nlohmann::json parameters;           ///< creation_parameters(request): the item's `creation_parameters`
  std::optional<GimResult> gim;        ///< Method::Gim
  std::optional<SphereResult> sphere;  ///< Method::Sphere
  std::optional<ReliefMap> relief;     ///< Method::Relief
  std::optional<McgimResult> mcgim;    ///< Method::Mcgim
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
  /// them as the attributes of the representation group, `batch` as the item's metrics. Also the frame
  /// origin, frame_origin_x/y/z: in a batch the only place an image item keeps it.
  std::map<std::string, double> numbers;
};

/// Runs the method on `mesh` (loaded under load_policy(request.method.method)) moved to its local frame,
/// and measures the result there (so neither depends on where the mesh lies: Conversion::origin).
/// Throws InvalidInput for options the method refuses (MethodOptions::check), the kernels' errors
/// (TopologyError, InvalidInput, ...), and Cancelled when the progress callback stops it; errors about the
/// mesh start with request.source.
[[nodiscard]] Conversion convert_mesh(const EmbreeDevice& device, const TriMesh& mesh, const ConversionRequest& request);
/// The same, moving `mesh` into the local frame in place: no copy of a huge input (the caller's is consumed).
[[nodiscard]] Conversion convert_mesh(const EmbreeDevice& device, TriMesh&& mesh, const ConversionRequest& request);

/// The stages of convert_mesh, for conversions whose input no process holds whole (jobs/brick_convert.h).
/// Throws InvalidInput "SOURCE: the mesh lies D from the origin; archives hold local frames within ±1e12 of
/// it" unless `origin` (local_frame_origin of the mesh) is within kMaxFrameOrigin: what begin_conversion and
/// `validate` refuse, since no reader would take the archive back.
void check_frame_origin(const std::string& source, const Vec3& origin);

/// begin_conversion: the identity, parameters and frame origin (checks the options: InvalidInput).
[[nodiscard]] Conversion begin_conversion(const ConversionRequest& request, std::size_t input_vertices,
                                          std::size_t input_faces, const Vec3& origin);
/// The method's kernel on `mesh` (in the local frame) and its statistics; errors named as convert_mesh's.
/// `wrap`: the --wrap value when `mesh` is a wrap of the input (errors are then named as its wrap's).
void run_method(const EmbreeDevice& device, const TriMesh& mesh, const ConversionRequest& request, Conversion& c,
                const std::string& wrap = {});
/// An image made from a proxy is optimized (--optimize, Sander et al. §4.6) after its samples have moved onto
/// the full surface, against that surface: fitted to the proxy, the transfer would undo the fit (the closed
/// dragon's 1.33M-face wrap: 75.6 dB fitted to its proxy, BENCHMARKS.md "The fit after the transfer").
/// fit_reference_samples: how many area samples of the full surface that fit uses, max(the fit's
/// reference_samples, 4 per image sample) — what one process draws with sample_surface and the ranks of a
/// brick conversion with brick_samples, with fit_reference_seed. fit_image: the fit against them, recorded
/// in c's numbers and statistics as the method's own --optimize records it.
[[nodiscard]] std::size_t fit_reference_samples(const Conversion& c);
[[nodiscard]] std::uint64_t fit_reference_seed();
void fit_image(const EmbreeDevice& device, std::span<const Vec3> reference_samples, Conversion& c,
               const ProgressCallback& progress);
/// What the fidelity of an image method compares with the input (gim fused at level 0, sphere level 0 with
/// holes open, mcgim §3). Throws InvalidInput for relief.
[[nodiscard]] TriMesh image_reconstruction(const Conversion& c);
/// The relief kernel's options from the request's method options (progress included).
[[nodiscard]] ReliefOptions relief_options(const ConversionRequest& request);
/// Records the statistics of c.relief (occlusion_ratio, samples, storage_bytes, timings, ...).
void record_relief(Conversion& c);
/// Records the fidelity (psnr, hausdorff_rms, hausdorff_max, bbox_diagonal).
void record_fidelity(Conversion& c, const HausdorffResult& fidelity);
/// Records the frame origin, the timings and the time of creation.
void finish_conversion(Conversion& c, double seconds_construct, double seconds_metric, double seconds_total);

/// Writes `conversion` as representation `name` of `archive` (/gim/<name>, /spherical/<name> or
/// /relief/<name>, docs/archive.md) with its source and Conversion::numbers as its record, its frame origin
/// and its provenance (write_item_facts); the root then describes the archive as a whole: `modified` and
/// `modified_by` (this conversion's time and command line) and `creation_parameters` =
/// kConvertArchiveParameters (`created`, `creator` stay those of the first; a batch archive keeps its job's
/// `creation_parameters`, which its `--resume` compares).
/// Throws as the io writers do (invalid name, taken name, HDF5 failure).
void write_conversion(io::Archive& archive, const std::string& name, const Conversion& conversion);

/// Writes the attribute `frame_origin` (float64[3]) of an item's group (docs/archive.md, "Local frame").
void write_frame_origin(h5::Group& group, const Vec3& origin);

/// Writes on an item's group what is not its record: `frame_origin` (float64[3], Conversion::origin) and the
/// provenance: `gimforge_version`, `command_line`, `created`, `creation_parameters` (JSON text).
void write_item_facts(h5::Group& group, const Conversion& conversion);

/// The origin of the local frame of an item's group (attribute `frame_origin`): what to add to every
/// position read from it (gim and sphere `geometry`, the relief map's `origin`) to get the input's
/// coordinates. Zero when absent (archives written before the local frame). Throws FormatError
/// "WHERE: attribute frame_origin is not 3 finite numbers within ±1e12" when it is anything else; `where`
/// names the group (e.g. "out.h5:/gim/bunny").
[[nodiscard]] Vec3 item_origin(const h5::Group& group, std::string_view where);
/// The largest |coordinate| of a frame origin read back.
inline constexpr double kMaxFrameOrigin = 1e12;
/// The same for representation `name` of `kind` in `archive` (FormatError from the representation layer
/// when the archive holds no such item).
[[nodiscard]] Vec3 item_origin(const io::Archive& archive, Method kind, const std::string& name);

/// How to write a mesh moved back to the input's coordinates (e.g. a reconstruction after
/// to_input_frame): binary PLY, in double when float32 would resolve its largest coordinate coarser than
/// 1e-6 of its bounding-box diagonal (a mesh far from the origin), float otherwise.
[[nodiscard]] io::PlyWriteOptions ply_options_for(const TriMesh& mesh);

/// The process's command line, recorded on every item it writes (`command_line`): set once by the
/// executable's main before any conversion. set_command_line(argc, argv) joins the arguments with spaces,
/// quoting those a shell would split or expand ('...'); the string overload stores the text as given.
void set_command_line(int argc, const char* const* argv);
void set_command_line(std::string text);
/// The process's command line; empty until set.
[[nodiscard]] std::string command_line();

/// What a batch stores for one converted item: the channel-first image and mask of gim and sphere
/// (stacked into (N, C, H, W) by the merge), or, for relief maps and multi-chart images (whose sizes differ
/// from item to item), a `representation` writer that fills the item's group with the layout of
/// /relief/<name> or /mcgim/<name>; Conversion::numbers become the item's metrics.
struct BatchItem {
  io::ItemArrays arrays;
  io::RepresentationWriter representation;  ///< empty for image methods
};
/// The item refers to `conversion` (the relief writer reads its map): keep the conversion alive until the
/// shard is written. A temporary cannot be passed.
[[nodiscard]] BatchItem batch_item(const Conversion& conversion);
BatchItem batch_item(Conversion&&) = delete;

/// A conversion's parameters: the method's options and the metric settings, e.g. {"method": "gim", "size":
/// 257, ..., "metric": true, "metric_samples": 1000000}: every item records its own (`creation_parameters`
/// of its group). They describe one conversion, not an archive that later ones append to: write_conversion
/// replaces the root's `creation_parameters` with kConvertArchiveParameters.
[[nodiscard]] nlohmann::json creation_parameters(const ConversionRequest& request);

/// The root's `creation_parameters` of an archive `convert` writes: true of every conversion in it.
inline constexpr std::string_view kConvertArchiveParameters = R"({"command":"convert"})";

}  // namespace gimforge::jobs
