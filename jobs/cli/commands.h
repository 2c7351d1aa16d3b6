#pragma once
/// \file commands.h
/// The subcommands of the gimforge executable: option structs filled by the CLI (cli.cpp) and the
/// functions that run them. Each returns a process exit code (exit_codes.h) and throws gimforge::Error
/// on failure, which main() turns into one "gimforge: error: ..." line and exit code 1.
#include <cstdint>
#include <string>
#include <vector>

#include "jobs/batch_run.h"
#include "jobs/method.h"

namespace gimforge::cli {

/// `gimforge info MESH [--json]`
struct InfoOptions {
  std::string mesh;
  bool json{false};
};
int run_info(const InfoOptions& options);

/// `gimforge validate MESH... [--json] [--allow-non-manifold] [--allow-inconsistent-orientation]`
struct ValidateCmdOptions {
  std::vector<std::string> meshes;
  bool json{false};
  bool allow_non_manifold{false};
  bool allow_inconsistent_orientation{false};
};
int run_validate(const ValidateCmdOptions& options);

/// `[mpirun -n N] gimforge metrics A B [--samples N] [--seed S] [--no-vertices] [--json]`
struct MetricsOptions {
  std::string a;
  std::string b;
  std::size_t samples{1'000'000};
  std::uint64_t seed{0x9e3779b97f4a7c15ull};
  bool include_vertices{true};
  bool json{false};
  bool progress{true};
  int threads{0};  ///< -j (0: not given: one thread per rank under mpirun, all cores alone)
};
int run_metrics(const MetricsOptions& options);

/// `gimforge convert-format IN -o OUT.ply [--precision auto|float|double] [--positions-only] [--json]`: any
/// mesh format rewritten as the binary PLY of triangles that the brick paths read in pieces (io/ply_ranges.h).
struct ConvertFormatOptions {
  std::string input;
  std::string output;
  std::string precision{"auto"};  ///< auto: double where float would change a coordinate, else float
  bool positions_only{false};     ///< drop normals and colours (relief by bricks reads only x y z records)
  bool weld{false};               ///< weld_positions, then repair_mesh
  bool json{false};
};
int run_convert_format(const ConvertFormatOptions& options);

/// `gimforge synth subdivide BASE (--segments N | --faces F) ... -o OUT.ply` and `gimforge synth terrain
/// (--grid NX[,NY] | --faces F) ... -o OUT.ply`: synthetic scans written piece by piece (kernels/scan/synth.h)
struct SynthOptions {
  std::string kind;                 ///< "subdivide" or "terrain"
  std::string base;                 ///< subdivide: the base mesh
  std::uint32_t segments{2};        ///< subdivide: pieces per base edge
  std::uint64_t faces{0};           ///< target face count (sets segments or the grid); 0: not given
  double amplitude{0.002};          ///< subdivide: displacement / bbox diagonal
  double wavelength{0.01};          ///< subdivide: shortest wave / bbox diagonal
  std::vector<std::uint32_t> grid;  ///< terrain: NX[,NY] quads
  double spacing{1.0};              ///< terrain: grid spacing
  double relief{0.05};              ///< terrain: relief / side
  double noise{0.1};                ///< terrain: per-vertex noise / spacing
  std::uint32_t holes{8};           ///< terrain: round holes
  double hole_radius{0.03};         ///< terrain: hole radius / side
  std::uint64_t seed{1};
  std::vector<double> offset;       ///< X,Y,Z added to every position (georeferencing); implies double output
  bool double_precision{false};
  std::string output;
  bool json{false};
  bool progress{true};
};
int run_synth(const SynthOptions& options);

/// `gimforge convert MESH --method gim|sphere|relief [the method's options] -o OUT.h5 [--name NAME] ...`
struct ConvertOptions {
  std::string mesh;
  jobs::MethodOptions method;       ///< --method and the method's options (jobs/method.h)
  std::string output;
  std::string name;                 ///< default: the mesh file's stem
  std::string sphere_map;           ///< sphere: "ARCHIVE[:NAME]": reuse that stored sphere map, do not optimize
  std::size_t metric_samples{1'000'000};
  bool no_metric{false};            ///< --no-metric: no fidelity report
  bool json{false};
  bool progress{true};
  int threads{0};  ///< -j (0: not given: one thread per rank under mpirun, all cores alone)
  bool wait{false};                 ///< --wait: another writer of the archive holds it: wait, do not fail
  bool xdmf{false};                 ///< --xdmf: also write the archive's XDMF sidecar ARCHIVE.xmf (io/xdmf.h)
  std::string command_line;         ///< recorded in a new archive's `creator`
};
int run_convert(const ConvertOptions& options);

/// `gimforge reconstruct ARCHIVE [--name NAME] [--level K] [--no-fuse] -o MESH.ply` (geometry images,
/// spherical geometry images, relief maps and multi-chart images; NAME may be qualified as gim/NAME,
/// spherical/NAME, relief/NAME or mcgim/NAME)
struct ReconstructOptions {
  std::string archive;
  std::string name;
  std::uint32_t level{0};
  std::string output;
  bool no_fuse{false};  ///< geometry images only: keep the open disk
};
int run_reconstruct(const ReconstructOptions& options);

/// `gimforge compress ARCHIVE [--name NAME] (--bytes B | --psnr P | --lossless) [--codec C] -o OUT.h5 [--json]`
/// (jobs/compress.h): every geometry image and spherical geometry image (or the one named) quantized or coded
/// into OUT.h5; readers decode them transparently.
struct CompressCmdOptions {
  std::string archive;
  std::string name;
  std::string output;
  std::string codec{"auto"};
  std::uint64_t bytes{0};
  double psnr{0.0};
  bool lossless{false};
  bool no_metric{false};
  std::size_t metric_samples{200'000};
  bool json{false};
  bool wait{false};
};
int run_compress(const CompressCmdOptions& options);

/// `gimforge decompress ARCHIVE [--name NAME] -o OUT.h5`: compressed items back to float32 (jobs/compress.h).
struct DecompressCmdOptions {
  std::string archive;
  std::string name;
  std::string output;
  bool wait{false};
};
int run_decompress(const DecompressCmdOptions& options);

/// `gimforge preview ARCHIVE [--name NAME] -o DIR` (geometry images, spherical geometry images, relief maps)
struct PreviewOptions {
  std::string archive;
  std::string name;
  std::string output_dir;
};
int run_preview(const PreviewOptions& options);

/// `gimforge render ARCHIVE [--name NAME] [--view AZ,EL] [--size 512] -o IMAGE.png [--reference MESH] [--json]`:
/// ray casting of a relief map (Apaza & Andújar §3.5.2, kernels/relief/relief_raycast.h); with --reference the
/// original mesh is rendered with Embree from the same camera into IMAGE_reference.png and the two
/// images are compared (PSNR of the shaded images, silhouette IoU).
struct RenderOptions {
  std::string archive;
  std::string name;                 ///< NAME or relief/NAME; default: the only relief map of the archive
  std::string view{"30,20"};        ///< "AZIMUTH,ELEVATION" in degrees (orbit camera)
  std::uint32_t size{512};          ///< image width and height
  std::string output;               ///< PNG of the ray-cast image
  std::string reference;            ///< mesh to render with Embree beside it (empty: none)
  std::string up{"y"};              ///< up axis of the orbit: x, y or z
  double fov{30.0};                 ///< vertical field of view in degrees
  std::uint32_t steps{12};          ///< linear-search samples per cell
  std::uint32_t refine{6};          ///< binary-search steps
  std::string filter{"bilinear"};   ///< "bilinear" or "nearest"
  bool json{false};
};
int run_render(const RenderOptions& options);

/// `gimforge batch ...`, alone or under mpirun / srun (cmd_batch.cpp, jobs/batch_run.h, docs/cli.md).
using BatchOptions = jobs::BatchOptions;
int run_batch(const BatchOptions& options);

/// `gimforge ls ARCHIVE [--json] [--xdmf]`: what the archive holds (jobs/archive_listing.h); --xdmf also
/// writes its XDMF sidecar ARCHIVE.xmf for ParaView / VisIt.
struct LsOptions {
  std::string archive;
  bool json{false};
  bool xdmf{false};
};
int run_ls(const LsOptions& options);

/// Parses the command line and runs the chosen subcommand (cli.cpp).
int main(int argc, char** argv);

/// The options every command takes (before the command's name).
struct GlobalOptions {
  std::string log_level{"info"};
  bool verbose{false};
  bool quiet{false};
  int threads{0};
};

/// Every subcommand's options, filled by CLI11 (cli.cpp).
struct Commands {
  InfoOptions info;
  ValidateCmdOptions validate;
  MetricsOptions metrics;
  ConvertOptions convert;
  BatchOptions batch;
  ReconstructOptions reconstruct;
  CompressCmdOptions compress;
  DecompressCmdOptions decompress;
  PreviewOptions preview;
  RenderOptions render;
  LsOptions ls;
  SynthOptions synth;
  ConvertFormatOptions convert_format;
};

}  // namespace gimforge::cli
