// The command-line interface (CLI11 is confined to this translation unit: it is slow to compile).
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <initializer_list>
#include <string_view>
#include <thread>
#include <algorithm>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "gimforge_version.h"
#include "io/printable.h"
#include "jobs/batch_job.h"
#include "jobs/cli/commands.h"
#include "jobs/cli/crash_guard.h"
#include "jobs/cli/exit_codes.h"
#include "jobs/cli/option_values.h"
#include "jobs/logging.h"
#include "jobs/pipeline.h"
#include "mpi/environment.h"
#include "kernels/core/errors.h"

namespace gimforge::cli {
namespace {

constexpr const char* kFooter = R"(
Exit codes: 0 success, 1 error (one line on stderr names the file and the cause), 2 usage error,
3 a batch finished with some failed items, 4 a batch stopped by a signal (resumable with --resume).
Mesh formats read: PLY (ascii, binary little/big endian), OBJ, OFF, STL (ascii, binary).
Documentation: docs/cli.md, docs/archive.md.)";

/// The largest -j: far beyond any useful thread count, small enough that a typo (-j 100000) is caught.
int max_threads() { return std::max(1024, 4 * static_cast<int>(std::thread::hardware_concurrency())); }

using jobs::kMaxGimSize;  ///< the largest geometry image --size (an 8193 x 8193 image; jobs/batch_job.h)

void add_global_options(CLI::App& app, GlobalOptions& g) {
  app.add_option("--log-level", g.log_level, "Log level: trace, debug, info, warn, error, off")
      ->capture_default_str()
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "off"}));
  app.add_flag("-v,--verbose", g.verbose, "Same as --log-level debug");
  app.add_flag("-q,--quiet", g.quiet, "Same as --log-level error (no warnings, no progress)");
  app.add_option("-j,--threads", g.threads, "Worker threads (default, or 0: all cores)")->check(CLI::Range(0, max_threads()));
}

void add_info(CLI::App& app, InfoOptions& o) {
  auto* cmd = app.add_subcommand("info", "Describe a mesh: size, components, boundary loops, genus, flags, defects");
  cmd->add_option("mesh", o.mesh, "Mesh file (.ply .obj .off .stl)")->required();
  cmd->add_flag("--json", o.json, "Print JSON (keys: vertices faces components boundary_loops genus closed "
                                  "manifold bbox_diagonal ...; see docs/cli.md)");
  cmd->footer("Repairable defects (degenerate faces, duplicate faces, unreferenced vertices) are repaired with a\n"
              "warning before the topology is computed; fatal ones (indices out of range, NaN/Inf coordinates) are\n"
              "errors. Vertices at one position are reported and kept (convert-format --weld welds them).");
}

void add_validate(CLI::App& app, ValidateCmdOptions& o) {
  auto* cmd = app.add_subcommand(
      "validate", "Check meshes for the defects the conversion methods refuse (exit 1 if any file fails)");
  cmd->add_option("meshes", o.meshes, "Mesh files")->required();
  cmd->add_flag("--json", o.json, "Print the defects found as JSON");
  cmd->add_flag("--allow-non-manifold", o.allow_non_manifold, "Accept non-manifold edges and vertices");
  cmd->add_flag("--allow-inconsistent-orientation", o.allow_inconsistent_orientation,
                "Accept faces whose orientations disagree");
  cmd->footer(
      "Fatal: indices out of range, NaN/Inf coordinates, no faces. Refused: non-manifold edges/vertices,\n"
      "inconsistent orientation (unless allowed). Repaired with a warning: degenerate faces, duplicate faces,\n"
      "unreferenced vertices. Reported only: zero-area faces, vertices sharing a position.");
}

void add_metrics(CLI::App& app, MetricsOptions& o) {
  auto* cmd = app.add_subcommand(
      "metrics", "Symmetric Hausdorff distance and PSNR between two surfaces (the papers' fidelity measure)");
  cmd->add_option("a", o.a, "Original mesh (its bounding-box diagonal is the PSNR reference)")->required();
  cmd->add_option("b", o.b, "Mesh to compare (e.g. a reconstruction)")->required();
  cmd->add_option("-n,--samples", o.samples, "Area-weighted samples per direction")
      ->capture_default_str()
      ->check(CLI::Range(std::size_t{1}, jobs::kMaxMetricSamples));
  cmd->add_option("--seed", o.seed, "Seed of the sample positions (results are deterministic)")->capture_default_str();
  cmd->add_flag("!--no-vertices", o.include_vertices, "Do not add the meshes' vertices to the samples");
  cmd->add_flag("--json", o.json, "Print JSON: {diag, ab:{max,mean,rms}, ba:{...}, max, rms, psnr}");
  cmd->footer(
      "d = sqrt((rms_ab^2 + rms_ba^2)/2), PSNR = 20 log10(diag/d), diag = A's bounding-box diagonal.\n"
      "Distances are exact point-to-triangle distances (Embree point queries). mean and rms are over the\n"
      "area-weighted samples; max also covers every vertex. Under mpirun / srun --mpi=pmix the ranks split the\n"
      "work and rank 0 prints the same result, bit for bit, as one process (one thread per rank unless -j).\n"
      "Two binary PLY files of triangles are split into spatial bricks: no rank reads either mesh whole, so\n"
      "memory per rank falls with the rank count (-v logs each rank's brick and phases). Other formats are\n"
      "read whole by every rank.");
}

void add_convert_format(CLI::App& app, ConvertFormatOptions& o) {
  auto* cmd = app.add_subcommand("convert-format", "Rewrite a mesh (PLY, OBJ, OFF, STL) as a binary PLY of triangles, the "
                                                   "layout mpirun reads in pieces");
  cmd->add_option("input", o.input, "Mesh file (.ply .obj .off .stl)")->required();
  cmd->add_option("-o,--output", o.output, "Output .ply (binary little-endian)")->required();
  cmd->add_option("--precision", o.precision, "auto: double where float would change a coordinate or, for an input "
                                              "stored as double or text, resolve them coarser than 1e-6 of the "
                                              "bounding-box diagonal; else float")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "float", "double"}));
  cmd->add_flag("--positions-only", o.positions_only,
                "Write x y z only, no normals or colours (relief by bricks reads such files; others go to rank 0)");
  cmd->add_flag("--weld", o.weld, "Weld vertices at the same position (bit for bit), then drop the faces that makes "
                                  "degenerate or duplicate and the unused vertices: a triangle soup, or a mesh split "
                                  "along normal or texture seams, becomes one surface (a binary STL is read whole)");
  cmd->add_flag("--json", o.json, "Print JSON: {input, output, format, encoding, vertices, faces, triangulated, welded, "
                                  "removed_faces, precision, normals, colors, readable_in_pieces, relief_by_bricks, "
                                  "streamed, bytes, seconds}");
  cmd->footer("Polygons are fan-triangulated and STL corners welded exactly as every command reads them; nothing\n"
              "else is repaired unless --weld. The input is read whole (about 40 bytes per face and vertex; a binary\n"
              "STL is streamed in bounded memory); the output is written to a temporary file and renamed.\n"
              "Example: gimforge convert-format scan.obj -o scan.ply, then mpirun -n 4 gimforge convert scan.ply\n"
              "--method relief -o scan.h5 reads it by bricks.");
}

void add_synth(CLI::App& app, SynthOptions& o) {
  auto* cmd = app.add_subcommand("synth", "Write a synthetic scan of any size as binary PLY (test data for huge scans)");
  cmd->require_subcommand(1);
  const auto common = [&](CLI::App* sub) {
    sub->add_option("--faces", o.faces, "Target face count (sets the segments or the grid)")
        ->check(CLI::Range(std::uint64_t{1}, std::uint64_t{4'000'000'000}));
    sub->add_option("--seed", o.seed, "Seed of the displacement, noise and holes (same seed, same file)")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    sub->add_option("--offset", o.offset, "X,Y,Z added to every position (georeferenced, e.g. UTM); writes doubles")
        ->delimiter(',')
        ->expected(3);
    sub->add_flag("--double", o.double_precision, "Write double coordinates (default float, double with --offset)");
    sub->add_option("-o,--output", o.output, "Output .ply (binary little-endian)")->required();
    sub->add_flag("--json", o.json, "Print JSON: {output, vertices, faces, bytes, seconds, segments | grid}");
  };
  auto* sub = cmd->add_subcommand("subdivide", "Subdivide every face of a mesh 1-to-n² and displace it along the normals");
  sub->add_option("base", o.base, "Base mesh (.ply .obj .off .stl)")->required();
  auto* seg = sub->add_option("--segments", o.segments, "Pieces per base edge, n (faces = base faces · n²)")
                  ->capture_default_str()
                  ->check(CLI::Range(1u, 65535u));
  sub->add_option("--amplitude", o.amplitude, "Displacement amplitude, fraction of the bbox diagonal")->capture_default_str()->check(CLI::Range(0.0, 1.0));
  sub->add_option("--wavelength", o.wavelength, "Shortest displacement wave, fraction of the bbox diagonal")->capture_default_str()->check(CLI::Range(1e-9, 1000.0));
  common(sub);
  sub->get_option("--faces")->excludes(seg);
  sub->footer("A closed manifold base gives a closed manifold scan (same genus and components); edge vertices are\n"
              "shared exactly. Example: gimforge synth subdivide bunny.ply --faces 50000000 -o bunny50m.ply");
  sub->callback([&o] { o.kind = "subdivide"; });
  auto* ter = cmd->add_subcommand("terrain", "An open, noisy height field with round holes");
  auto* grid = ter->add_option("--grid", o.grid, "NX[,NY] quads (two triangles each)")
                   ->delimiter(',')
                   ->expected(1, 2)
                   ->type_name("NX[,NY]")
                   ->check(CLI::Range(1u, 65535u));
  ter->add_option("--spacing", o.spacing, "Grid spacing")->capture_default_str()->check(CLI::Range(1e-9, 1e9));
  ter->add_option("--relief", o.relief, "Relief amplitude, fraction of the side")->capture_default_str()->check(CLI::Range(0.0, 10.0));
  ter->add_option("--noise", o.noise, "Per-vertex noise, fraction of the spacing")->capture_default_str()->check(CLI::Range(0.0, 100.0));
  ter->add_option("--holes", o.holes, "Round holes (kept two cells apart; at most 10000)")
      ->capture_default_str()
      ->check(CLI::Range(0u, 10000u));
  ter->add_option("--hole-radius", o.hole_radius, "Hole radius, fraction of the side")->capture_default_str()->check(CLI::Range(0.0, 0.5));
  common(ter);
  ter->get_option("--faces")->excludes(grid);
  ter->footer("Give --grid or --faces. Example: gimforge synth terrain --faces 50000000 --offset 500000,4100000,300 -o t.ply");
  ter->callback([&o] {
    o.kind = "terrain";
    if (o.grid.empty() && o.faces == 0) throw CLI::RequiredError("synth terrain: --grid NX[,NY] or --faces F");
  });
}

/// Refuses options of one conversion method given with another (a usage error, exit 2).
void check_method_options(const CLI::App& cmd, const jobs::MethodOptions& o) {
  const OptionProblem problem = method_option_problem(o, [&](const char* name) {
    const CLI::Option* option = cmd.get_option_no_throw(name);
    return option != nullptr && option->count() > 0;
  });
  if (!problem.option.empty()) throw CLI::ValidationError(problem.option, problem.reason);
}

/// The method's own checks of its options (MethodOptions::check: e.g. --size 100), as a usage error (exit 2).
void check_method_values(const jobs::MethodOptions& o, const char* command) {
  try {
    o.check(command);
  } catch (const InvalidInput& e) {
    throw CLI::ValidationError(e.what());
  }
}

/// An option that is "auto" or a count, checked by the one parser of jobs/method.h: `field` selects the
/// MethodOptions member the parser reads, `parse` the parser (relief_grid, mcgim_charts). The text becomes
/// canonical ("04" is 4); the error is the parser's without its option name (CLI11 prefixes it).
CLI::Validator auto_or_count_validator(std::string jobs::MethodOptions::*field,
                                       std::uint32_t (jobs::MethodOptions::*parse)() const, const char* metavar) {
  return CLI::Validator(
      [field, parse](std::string& text) -> std::string {
        jobs::MethodOptions m;
        m.*field = text;
        try {
          const std::uint32_t n = (m.*parse)();
          if (n != 0) text = std::to_string(n);
        } catch (const InvalidInput& e) {
          // "--grid '04x' is neither 'auto' nor ..." -> "04x is neither auto nor ..."
          std::string what = e.what();
          if (const auto at = what.find(" is neither"); at != std::string::npos) what = text + what.substr(at);
          if (const auto at = what.find("'auto'"); at != std::string::npos) what.replace(at, 6, "auto");
          return what;
        }
        return {};
      },
      metavar);
}

/// --method, bound to the method enum (jobs/method.h); an unknown name is a usage error listing the methods.
void add_method_option(CLI::App* cmd, jobs::Method& method, const std::string& help) {
  std::vector<std::string> names;
  for (const jobs::Method m : jobs::kMethods) names.emplace_back(jobs::method_name(m));
  cmd->add_option_function<std::string>(
         "--method", [&method](const std::string& name) { method = jobs::parse_method(name); }, help)
      ->check(CLI::IsMember(names))
      ->default_str(std::string(jobs::method_name(method)));
}

/// The options of every method, as convert and batch take them (batch items have no normal map).
void add_method_options(CLI::App* cmd, jobs::MethodOptions& o, bool batch) {
  cmd->add_option("--size", o.size,
                  "gim: geometry image size n (n x n samples; n - 1 a multiple of 64: 65, 129, 257, 513, ... 8193)")
      ->capture_default_str()
      ->check(CLI::Range(std::uint32_t{65}, kMaxGimSize));
  if (!batch)
    cmd->add_option("--normal-size", o.normal_size, "gim: normal map resolution (0: none)")->capture_default_str();
  cmd->add_option("--max-augmentations", o.max_augmentations,
                  "gim: iterations of cut augmentation (0 keeps the initial cut)")
      ->capture_default_str()
      ->check(CLI::Range(0, jobs::kMaxAugmentations));
  cmd->add_option("--sampling", o.sampling,
                  "gim, sphere --domain flat-octa: where the samples lie in the parameter square: uniform (the "
                  "regular grid), or adaptive (docs/adaptive.md): from a start grid (--adapt-start), samples moved "
                  "along the gradient of the local Hausdorff distance between the input and the reconstruction; "
                  "the image keeps its size and grid, the sample positions are stored beside it")
      ->capture_default_str()
      ->check(CLI::IsMember({"uniform", "adaptive"}));
  cmd->add_option("--adapt-rounds", o.adapt_rounds,
                  "--sampling adaptive: at most K rounds of sample moves (each visits the faces within half of "
                  "the largest distance, worst first; it stops earlier when a round lowers neither the largest "
                  "distance nor the RMS by a thousandth; 0: the start grid as it is)")
      ->capture_default_str()
      ->check(CLI::Range(std::uint32_t{0}, jobs::kMaxAdaptRounds));
  cmd->add_option("--adapt-start", o.adapt_start,
                  "--sampling adaptive: the grid the moves start from: strips (the paper's vertex-density "
                  "equalization), uniform (the regular grid), or auto: whichever is closer to the input by the "
                  "RMS of the local Hausdorff distances (a stretch-minimizing parametrization already spreads the "
                  "samples by area, and the strips can lose there; docs/adaptive.md)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "uniform", "strips"}));
  cmd->add_option("--roi", o.roi,
                  "gim, or sphere with --domain flat-octa, --sampling adaptive: a region of interest that gets more samples, then the moves minimize "
                  "its directed Hausdorff distance (docs/adaptive.md): auto[:F] (the window of F of the square, "
                  "default 0.1, where the normal image varies most), box:X0,Y0,Z0,X1,Y1,Z1 (vertices in the box, "
                  "input coordinates), vertices:FILE (0-based vertex indices of the mesh file), color:RRGGBB "
                  "(vertices painted that colour), scalar:NAME[>T] (vertices whose PLY property NAME exceeds T, "
                  "default 0), mask:PNG (white pixels over the parameter square, as preview "
                  "draws the normal image, or a uniform flat-octa item's geometry picture)")
      ->check(CLI::Validator([](std::string& text) { return text.empty() ? "empty: it names no region (leave --roi out for none)" : ""; }, ""));
  cmd->add_option("--roi-gain", o.roi_gain,
                  "--roi: the ROI gets this many times its samples of the start grid before the moves")
      ->capture_default_str()
      ->check(CLI::Range(1.0, jobs::kMaxRoiGain));
  cmd->add_option("--domain", o.domain,
                  "sphere: domain polyhedron: octa ((2n+1)x(2n+1) image), tetra (2n x (n+1)), cube (6 faces of "
                  "(n+1)x(n+1)), flat-octa ((2n+1)x(2n+1))")
      ->capture_default_str()
      ->check(CLI::IsMember({"octa", "tetra", "cube", "flat-octa"}));
  cmd->add_option("--n", o.n, "sphere: tessellation number: n+1 samples per domain edge (128: a 257x257 octa image)")
      ->capture_default_str()
      ->check(CLI::Range(std::uint32_t{1}, jobs::kMaxSphereN));
  cmd->add_option("--grid", o.grid,
                  "relief: cells per axis N of the cubic grid over the bounding cube (1..1024), or auto: N = 1, 2, "
                  "4, ... while more than --occlusion-threshold of the surface samples are hidden, up to --max-grid")
      ->capture_default_str()
      ->transform(auto_or_count_validator(&jobs::MethodOptions::grid, &jobs::MethodOptions::relief_grid, "N|auto"));
  cmd->add_option("--texture", o.texture,
                  "relief: texels per side of the distance / normal map of every domain face (2..1024)")
      ->capture_default_str()
      ->check(CLI::Range(std::uint32_t{2}, jobs::kMaxReliefTexture));
  cmd->add_option("--max-grid", o.max_grid, "relief, --grid auto: largest N tried (1..1024)")
      ->capture_default_str()
      ->check(CLI::Range(std::uint32_t{1}, jobs::kMaxReliefGrid));
  cmd->add_option("--occlusion-threshold", o.occlusion_threshold,
                  "relief, --grid auto: keep N once hidden samples / all samples <= this (0..1)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--samples", o.samples,
                  "mcgim: bound on the image rectangle's area W x H, undefined samples included (the memory cost; "
                  "66049 = a 257 x 257 geometry image)")
      ->capture_default_str()
      ->check(CLI::Range(std::uint32_t{64}, jobs::kMaxMcgimSamples));
  cmd->add_option("--charts", o.charts,
                  "mcgim: number of charts K (1..4096; more are added where a chart would not be a disk or a "
                  "component has none), or auto: convert with 32 and 48 charts and keep the closer to "
                  "the input")
      ->capture_default_str()
      ->transform(auto_or_count_validator(&jobs::MethodOptions::charts, &jobs::MethodOptions::mcgim_charts, "K|auto"));
  cmd->add_option("--proxy-faces", o.proxy_faces,
                  "gim, sphere, mcgim: convert through a quadric-decimated proxy of F faces (OpenMesh), then move "
                  "every sample onto the full-resolution surface (along the proxy normal, or to the closest point), "
                  "so the image keeps the input's detail; off: parametrize every face; auto: a proxy of max(1000, "
                  "image samples / 4) faces (mcgim: one per sample) for inputs of more than 1,000,000 faces and more "
                  "than 4 faces per image sample")
      ->capture_default_str()
      ->check(CLI::Validator(
          [](std::string& text) -> std::string {
            jobs::MethodOptions m;
            m.proxy_faces = text;
            try {
              (void)m.proxy_target(0);
            } catch (const InvalidInput& e) {
              std::string what = e.what();
              if (const auto at = what.find(" is neither"); at != std::string::npos) what = text + what.substr(at);
              return what;
            }
            return {};
          },
          "F|auto|off"));
  cmd->add_option("--proxy-bricks", o.proxy_bricks,
                  "gim, sphere, mcgim with a proxy: k-d bricks of the input's vertices that are decimated first, each "
                  "on its own with the vertices it shares locked, before the welded pieces are decimated whole; "
                  "0: auto (about 250,000 input faces and at least 4,096 proxy faces per brick). The proxy depends "
                  "on the bricks, never on threads or ranks; in batch each brick is a task of its own")
      ->capture_default_str()
      ->check(CLI::Range(std::uint32_t{0}, jobs::kMaxProxyBricks));
  cmd->add_option("--wrap", o.wrap,
                  "gim, sphere, mcgim: convert through a closed one-piece wrap of the mesh (OpenVDB): voxelized at R "
                  "voxels along its longest side (16..2048), holes and tunnels narrower than about 2C voxels closed "
                  "(C 0..16, default 1), the largest piece kept, decimated to the proxy size; the image's samples then "
                  "move onto the mesh itself. For scans of many components, holes and handles (e.g. --wrap 512)")
      ->capture_default_str();
  cmd->add_flag("--optimize", o.optimize,
                "gim, sphere, mcgim: geometry-image optimization (Sander et al. 2003 sec. 4.6): move the samples to "
                "fit the input surface (conjugate gradients, dihedral-angle smoothness); glued, same-domain-point "
                "and zippered samples move together, so a closed image stays closed");
}

/// What every command that writes an archive takes (convert, batch): --wait and --xdmf.
void add_archive_writer_flags(CLI::App* cmd, bool& wait, bool& xdmf) {
  cmd->add_flag("--wait", wait,
                "When another gimforge is writing the archive (ARCHIVE.lock is held), wait for it instead of "
                "failing");
  cmd->add_flag("--xdmf", xdmf,
                "Also write an XDMF sidecar beside the archive (its extension replaced: out.h5 -> out.xmf) that opens the "
                "archive's images in ParaView / VisIt (docs/archive.md)");
}

void add_convert(CLI::App& app, ConvertOptions& o) {
  auto* cmd = app.add_subcommand("convert", "Convert a mesh to a regular representation stored in an HDF5 archive");
  cmd->add_option("mesh", o.mesh,
                  "Input mesh (.ply .obj .off .stl): one connected 2-manifold (--method sphere: of genus 0, holes "
                  "allowed; --method mcgim: any triangle mesh, several components, non-manifold and misoriented parts cut into boundaries; --method relief: any triangle mesh)")
      ->required();
  add_method_option(cmd, o.method.method,
                    "Representation: gim (geometry image, Gu et al. 2002), sphere (spherical geometry image, Praun "
                    "& Hoppe 2003), relief (relief map on cubic cells, Apaza & Andujar) or mcgim (multi-chart "
                    "geometry image, Sander et al. 2003)");
  cmd->add_option("-o,--output", o.output,
                  "Archive to create or add to (.h5); an existing archive is copied, extended and renamed over the "
                  "original, so a failed run leaves it as it was")
      ->required();
  cmd->add_option("--name", o.name, "Name of the result in the archive (default: the mesh file's stem)")
      ->check(CLI::Validator([](const std::string& text) {  // what the archive takes (io/representation.h)
        const std::string why = io::path_component_problem(text);
        return why.empty() ? why : "it " + why + " (a name is one file-name component: no '/', '.' or '..')";
      }, "NAME"));
  add_archive_writer_flags(cmd, o.wait, o.xdmf);
  add_method_options(cmd, o.method, /*batch=*/false);
  cmd->add_option("--sphere-map", o.sphere_map,
                  "sphere: ARCHIVE[:NAME]: resample the sphere map stored with spherical image NAME (default: the "
                  "mesh file's stem) instead of optimizing one; the mesh must be the one it was made for");
  auto* samples = cmd->add_option("--metric-samples", o.metric_samples,
                                  "Samples per direction for the PSNR against the input")
                      ->capture_default_str()
                      ->check(CLI::Range(std::size_t{1}, jobs::kMaxMetricSamples));
  cmd->add_flag("--no-metric", o.no_metric,
                "Skip the fidelity report (PSNR, Hausdorff distances): the archive then records none")
      ->excludes(samples);
  cmd->add_flag("--json", o.json, "Print the summary as JSON");
  cmd->callback([cmd, &o] {
    check_method_options(*cmd, o.method);
    check_method_values(o.method, "convert");
  });
  cmd->footer(
      "Geometry images (--method gim): the mesh is cut into a disk (cut augmented through its extremities while\n"
      "the stretch improves), parametrized onto the unit square minimizing geometric stretch (progressive-mesh\n"
      "coarse-to-fine), and resampled on an n x n grid; the archive stores the image, the normal map, the\n"
      "topological sideband, cut statistics, stretch efficiency, PSNR against the input and timings.\n"
      "Spherical geometry images (--method sphere): a genus-0 mesh (holes are filled, their samples stored as\n"
      "NaN with a mask) is parametrized onto the sphere minimizing spherical stretch, and resampled through a\n"
      "domain polyhedron (--domain) unfolded into an image with n+1 samples per domain edge (--n). No cut:\n"
      "the image boundary is glued by symmetry. The archive stores the image, the mask, the per-vertex sphere\n"
      "map, stretch efficiencies (S->M, D->S, D->M), PSNR against the input and timings. Other genus: use gim.\n"
      "Relief maps (--method relief): any triangle mesh (several components, holes, non-manifold edges are fine)\n"
      "is enclosed in a cube of N^3 cells (--grid); cells meeting the surface are grey, the others white (outside)\n"
      "or black (inside: OpenVDB flood fill for watertight meshes, else a parity-vote fallback, reported). Every\n"
      "grey cell projects its part of the surface onto its domain faces (external faces, or all six for interior\n"
      "grey cells) by one of four projections chosen by its configuration (10 cases), and every domain face stores\n"
      "a T x T map (--texture) of 16-bit distances and 8-bit normals (and colours). With --grid auto, N doubles\n"
      "while too many samples are hidden behind others (--occlusion-threshold) up to --max-grid. The archive stores\n"
      "the cell table, the maps, the grids tried, PSNR of the reconstruction against the input and timings.\n"
      "Multi-chart geometry images (--method mcgim): any triangle mesh (several components, holes, any genus;\n"
      "non-manifold edges and orientation conflicts are cut into boundaries first, docs/multichart.md) is\n"
      "partitioned into K disk charts (Lloyd clustering on the dual graph, --charts), each parametrized with a free\n"
      "boundary minimizing stretch, packed (16 orientations) into a W x H rectangle of at most --samples samples,\n"
      "sampled (samples outside the charts are undefined: NaN with a mask) and zippered so that the\n"
      "reconstruction is watertight for a closed input; --optimize then fits the samples to the input. The archive\n"
      "stores the image, mask, chart ids, zipper table, normals, per-chart and total stretch, packing efficiency,\n"
      "PSNR against the input and timings (docs/multichart.md).");
}

void add_reconstruct(CLI::App& app, ReconstructOptions& o) {
  auto* cmd = app.add_subcommand(
      "reconstruct",
      "Rebuild a triangle mesh from a geometry image, spherical or multi-chart geometry image, or relief map");
  cmd->add_option("archive", o.archive, "Archive (.h5)")->required();
  cmd->add_option("--name", o.name,
                  "Image to use: NAME, or qualified by its group: gim/NAME, spherical/NAME, relief/NAME or mcgim/NAME, "
                  "or an item of a batch archive: batch/OUTPUT/ITEM (e.g. batch/gim_257/chair/0001) (default: the only "
                  "one)");
  cmd->add_option("--level", o.level,
                  "Level of detail: sub-sample by 2^level (gim: crack-free down to 65 x 65; sphere: while n / 2^level "
                  "is a whole number, down to n = 1; relief and mcgim: level 0 only)")
      ->capture_default_str();
  cmd->add_flag("--no-fuse", o.no_fuse, "gim: do not glue the image boundary from the sideband (an open disk); mcgim: ignore the zipper (every "
                "chart its own open disk)");
  cmd->add_option("-o,--output", o.output, "Output mesh: .ply (binary), .obj, .off or .stl (the extension names the format)")
      ->required();
  cmd->footer(
      "Spherical geometry images reconstruct closed and watertight with the domain's own connectivity; faces\n"
      "touching undefined samples (filled holes) are left out, so the input's holes stay open.\n"
      "Relief maps: every non-empty texel is unprojected to its surface point, every 2x2 texel quad of a domain\n"
      "face becomes two triangles (dropped across depth jumps; texels no triangle uses are left out); one level\n"
      "only, the pieces of the faces are not stitched together.");
}

void add_compress(CLI::App& app, CompressCmdOptions& o) {
  auto* cmd = app.add_subcommand(
      "compress", "Quantize or code the geometry images (gim, spherical, multi-chart) of an archive into a new one");
  cmd->add_option("archive", o.archive, "Archive (.h5) holding the images")->required();
  cmd->add_option("--name", o.name, "Image to compress: NAME, gim/NAME, spherical/NAME or mcgim/NAME (default: every one)");
  cmd->add_option("-o,--output", o.output, "Archive to write (created, or extended like convert -o)")->required();
  cmd->add_option("--codec", o.codec,
                  "auto: the better of j2k and wavelet at the target (multi-chart images: j2k); j2k: JPEG 2000 of the "
                  "16-bit planes (OpenJPEG); wavelet: the 9/7 lattice wavelet with local frames, square images only "
                  "(octahedral images: the spherical extension rules, watertight without fusing); quant12 / quant16: "
                  "positions quantized over the bounding box (normals and colours to 8 / 16 bits; multi-chart images "
                  "drop their normals, central differences of the positions); j2k-roi (with --bytes): JPEG 2000 with "
                  "the region of interest of an image converted with --roi coded first (docs/adaptive.md)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "j2k", "wavelet", "quant12", "quant16", "j2k-roi"}));
  auto* bytes = cmd->add_option("--bytes", o.bytes,
                                 "Stored bytes per item, everything counted: payload, sideband, mask, chart ids and "
                                 "zipper, attributes and names (>= 1024)")
                    ->check(CLI::Range(std::uint64_t{1024}, std::uint64_t{1} << 40));
  auto* psnr = cmd->add_option("--psnr", o.psnr, "Target PSNR (dB) of the decoded samples against the stored ones, in (0, 200]")
                   ->check(CLI::Validator([](const std::string& text) { return psnr_value_error(text); }, "(0, 200]"));
  auto* lossless = cmd->add_flag("--lossless", o.lossless, "j2k only: the reversible 5/3 wavelet of the 16-bit planes");
  bytes->excludes(psnr)->excludes(lossless);
  psnr->excludes(lossless);
  auto* no_metric = cmd->add_flag("--no-metric", o.no_metric,
                "Do not measure the surface PSNR (symmetric RMS Hausdorff) of the candidates; auto then picks by the "
                "PSNR of the samples' displacements along the stored surface's normals");
  cmd->add_option("--metric-samples", o.metric_samples, "Area samples per direction of the surface PSNR")
      ->capture_default_str()
      ->check(CLI::Range(std::size_t{1000}, std::size_t{1} << 26))->excludes(no_metric);
  cmd->add_flag("--wait", o.wait, "Wait for another writer of the output archive instead of failing");
  cmd->add_flag("--json", o.json, "Print JSON: {archive, items: [{item, codec, bytes_before, geometry_bytes_before, bytes, image_psnr, "
                                  "surface_psnr, seam_gap, roi_image_psnr, seconds, trials}]} (roi_image_psnr: the "
                                  "image PSNR over the samples of an item converted with --roi; null otherwise)");
  cmd->footer(
      "Coded items keep the sideband (gim), the mask (spherical) or mask, chart ids and zipper (mcgim), the frame\n"
      "origin and the original PSNR, and drop normal maps, colours, adaptive sample positions, the ROI mask and\n"
      "the sphere parametrization. reconstruct, preview and every reader decode them transparently; decoded geometry images\n"
      "are fused along the cut from the sideband, multi-chart ones along the zipper, and the fusing is diffused\n"
      "into the interior (Gu et al. 5). Layout: docs/archive.md, 'Compressed items'; rates and Draco:\n"
      "docs/compression.md.");
}

void add_decompress(CLI::App& app, DecompressCmdOptions& o) {
  auto* cmd = app.add_subcommand("decompress", "Write the compressed images of an archive back as float32 images");
  cmd->add_option("archive", o.archive, "Archive (.h5) written by compress")->required();
  cmd->add_option("--name", o.name, "Image: NAME, gim/NAME, spherical/NAME or mcgim/NAME (default: every one)");
  cmd->add_option("-o,--output", o.output, "Archive to write (created, or extended like convert -o)")->required();
  cmd->add_flag("--wait", o.wait, "Wait for another writer of the output archive instead of failing");
  cmd->footer("For readers without the codecs (h5py: JPEG 2000 needs glymur or Pillow with OpenJPEG, the wavelet\n"
              "coder is gimforge's own). Images are decoded and fused as reconstruct does; what compress dropped\n"
              "(normal maps, colours, the sphere parametrization) stays absent, except the normals of multi-chart\n"
              "images, which are central differences of the positions and are computed again.");
}

void add_preview(CLI::App& app, PreviewOptions& o) {
  auto* cmd = app.add_subcommand(
      "preview",
      "Write PNG pictures of a geometry image (xyz as rgb) and its normal map, of a spherical or multi-chart one, or "
      "of a relief map");
  cmd->add_option("archive", o.archive, "Archive (.h5)")->required();
  cmd->add_option("--name", o.name,
                  "Image to draw: NAME, or qualified by its group: gim/NAME, spherical/NAME, relief/NAME or mcgim/NAME, "
                  "or an item of a batch archive: batch/OUTPUT/ITEM, drawn into DIR/OUTPUT/ITEM_geometry.png and so on "
                  "(default: every image; the only item of a batch archive)");
  cmd->add_option("-o,--output", o.output_dir,
                  "Directory for NAME_geometry.png and NAME_normals.png (and NAME_roi.png, white over the region of "
                  "interest, for an image converted with --roi; spherical: NAME_sphere_geometry.png, "
                  "undefined samples yellow, and NAME_sphere_mask.png; mcgim: NAME_mcgim_geometry.png, undefined samples "
                  "yellow, NAME_mcgim_normals.png and NAME_mcgim_charts.png, a colour per chart, undefined black; "
                  "relief: NAME_relief_distances.png, "
                  "NAME_relief_normals.png, NAME_relief_colors.png and NAME_relief_cells.png)")
      ->required();
  cmd->footer(
      "Relief maps: the distance, normal (and colour) maps as atlases of all layers (domain faces) in table order\n"
      "(left to right, top to bottom), one T x T tile per layer, v growing upwards, tiles separated by dark blue\n"
      "lines; distances as grey (black = on the domain face, white = the longest distance stored), empty texels\n"
      "yellow. The cells picture shows the N z-slices of the grid (k = 0 first, j growing upwards): white and\n"
      "black cells white and black, border grey cells light grey, interior grey cells dark grey.");
}

void add_ls(CLI::App& app, LsOptions& o) {
  auto* cmd = app.add_subcommand("ls", "List what an archive holds: every representation and batch output with its "
                                       "method, size, PSNR and source");
  cmd->add_option("archive", o.archive, "Archive (.h5)")->required();
  cmd->add_flag("--json", o.json, "Print the listing as JSON");
  cmd->add_flag("--xdmf", o.xdmf,
                "Also write an XDMF sidecar beside the archive (its extension replaced: out.h5 -> out.xmf) that opens the "
                "geometry images, spherical images and batch stacks in ParaView / VisIt as structured grids");
  cmd->footer(
      "Reads attributes, shapes and HDF5's chunk index, no image data but the first and last values of each\n"
      "item's main dataset (the batch PSNR column reads one number per item). Names from the archive are\n"
      "printed with control characters escaped; an item that cannot be read, or whose data the file does not\n"
      "store whole, is listed as 'unreadable' with the reason, and ls then exits 1. Layout: docs/archive.md.");
}

void add_render(CLI::App& app, RenderOptions& o) {
  auto* cmd = app.add_subcommand("render", "Ray-cast a relief map into a PNG; compare it with an Embree render of the mesh");
  cmd->add_option("archive", o.archive, "Archive (.h5)")->required();
  cmd->add_option("--name", o.name,
                  "Relief map to use: NAME, relief/NAME or an item of a batch archive, batch/OUTPUT/ITEM (default: the "
                  "only one)");
  cmd->add_option("--view", o.view,
                  "Orbit camera: AZIMUTH,ELEVATION in degrees around the up axis (write --view=-30,10 for a negative "
                  "azimuth)")
      ->capture_default_str();
  cmd->add_option("--size", o.size, "Image width and height in pixels")->capture_default_str()->check(CLI::Range(1, 8192));
  cmd->add_option("-o,--output", o.output, "PNG of the ray-cast image (8-bit grey shading, background black)")
      ->required();
  cmd->add_option("--reference", o.reference,
                  "Original mesh: render it with Embree from the same camera into OUTPUT's name + _reference.png and "
                  "print the image PSNR and silhouette IoU");
  cmd->add_option("--up", o.up, "Up axis of the orbit")->capture_default_str()->check(CLI::IsMember({"x", "y", "z"}));
  cmd->add_option("--fov", o.fov, "Vertical field of view in degrees")->capture_default_str()->check(CLI::Range(1.0, 170.0));
  cmd->add_option("--steps", o.steps, "Linear-search samples per grid cell crossed")
      ->capture_default_str()
      ->check(CLI::Range(1, 1024));
  cmd->add_option("--refine", o.refine, "Refinement after the first inside sample, in halvings (binary search)")
      ->capture_default_str()
      ->check(CLI::Range(0, 32));
  cmd->add_option("--filter", o.filter, "Reading the distance maps: bilinear or nearest")
      ->capture_default_str()
      ->check(CLI::IsMember({"bilinear", "nearest"}));
  cmd->add_flag("--json", o.json, "Print the report as JSON");
  cmd->footer(
      "Apaza & Andujar, section 3.5.2: every pixel's ray walks the grid cells it crosses; in grey cells it is\n"
      "sampled (linear search, then refinement) against the distance maps of the cell's projection; the\n"
      "stored normals shade the hit (headlight Lambert + ambient). The camera looks at the centre of the box\n"
      "of the map's surface samples from the given azimuth and elevation, far enough for its bounding sphere\n"
      "to fit. With --reference both images come from the same camera and shading; IoU compares the hit masks.\n"
      "Prints the ray-casting speed (primary rays per second, all threads; -j sets them).");
}

void add_batch(CLI::App& app, BatchOptions& o) {
  auto* cmd = app.add_subcommand(
      "batch", "Convert a collection of meshes into one consolidated archive, with MPI ranks, resumable");
  auto* input = cmd->add_option("--input", o.input, "Directory searched recursively for .ply .obj .off .stl");
  auto* list = cmd->add_option("--list", o.list, "File with one mesh path per line (relative to the list's folder)");
  auto* job = cmd->add_option("--job", o.job, "TOML job file: collections, labels and several outputs (docs/cli.md)");
  input->excludes(list)->excludes(job);
  list->excludes(job);
  cmd->add_option("-o,--output", o.output, "Consolidated archive to write (.h5); must not exist unless --resume")
      ->required();
  const std::size_t first_output_option = cmd->get_options().size();  // through --label: what a job file sets
  add_method_option(cmd, o.method.method, "Without --job: the method of the single output (gim, sphere, relief or mcgim)");
  add_method_options(cmd, o.method, /*batch=*/true);
  cmd->add_option("--codec", o.method.codec,
                  "Without --job (job files: codec in [[output]]), gim, sphere and mcgim: store every item compressed "
                  "(docs/compression.md): auto, j2k, wavelet (with --rate), quant12, quant16, j2k-roi (gim with --roi: "
                  "the ROI first); the items become groups items/<k> laid out like compress's")
      ->check(CLI::IsMember({"auto", "j2k", "wavelet", "quant12", "quant16", "j2k-roi"}));
  cmd->add_option("--rate", o.method.rate,
                  "Without --job (job files: rate), with --codec auto|j2k|wavelet|j2k-roi: stored bytes per item, everything "
                  "counted (>= 1024)");
  cmd->add_option("--label", o.label, "Without --job: item labels: folder (parent folder name), none, or a fixed text")
      ->capture_default_str()->check(CLI::Validator([](std::string& text) { return label_value_error(text); }, ""));
  const std::size_t end_output_options = cmd->get_options().size();
  cmd->add_flag("--resume", o.resume, "Finish an interrupted batch from its journal (ARCHIVE.work/)");
  add_archive_writer_flags(cmd, o.wait, o.xdmf);
  cmd->add_option("--max-retries", o.max_retries, "Extra attempts for a failed item")
      ->capture_default_str()
      ->check(CLI::Range(0, 100));
  cmd->add_option("--item-timeout", o.item_timeout, "Seconds per item and attempt before it counts as failed (0: none)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e9));
  cmd->add_option("--worker-timeout", o.worker_timeout,
                  "Seconds rank 0 waits for a worker's answer on one item before giving up on that rank (hung, "
                  "stopped, node gone): the item counts as a failed attempt, the other ranks go on, and the job ends "
                  "with MPI_Abort once everything else is safe (exit 4 when the item still has attempts: --resume). "
                  "Default: 2 x --item-timeout + 60 with --item-timeout, else none; 0: none")
      ->check(CLI::Range(0.0, 1e9));
  cmd->add_option("--log-dir", o.log_dir, "Also write each rank's log (with time stamps) to LOG_DIR/rank-<r>.log");
  auto* samples = cmd->add_option("--metric-samples", o.metric_samples, "Samples per direction for each item's PSNR")
                      ->capture_default_str()
                      ->check(CLI::Range(std::size_t{1}, jobs::kMaxMetricSamples));
  cmd->add_flag("--no-metric", o.no_metric, "No fidelity report per item (no psnr / hausdorff_* metrics)")
      ->excludes(samples);
  cmd->allow_extras()->fallthrough(false);  // a stray word gets the hint below (the global options: main)
  cmd->callback([cmd, input, list, job, samples, first_output_option, end_output_options, &o] {
    o.metric_samples_set = samples->count() > 0;
    if (const std::vector<std::string> extra = cmd->remaining(); !extra.empty()) {
      if (extra.front().starts_with('-')) throw CLI::ExtrasError(extra);
      throw CLI::ValidationError(extra.front(), "batch takes no positional argument: give the meshes with --input DIR, --list FILE or --job JOB.toml");
    }
    if (input->count() + list->count() + job->count() != 1)
      throw CLI::ValidationError("--input/--list/--job", "give exactly one of --input DIR, --list FILE or --job JOB.toml");
    const std::vector<CLI::Option*> options = cmd->get_options();
    for (std::size_t i = first_output_option; job->count() > 0 && i < end_output_options; ++i)
      if (options.at(i)->count() > 0)
        throw CLI::ValidationError(options[i]->get_name(), "describes the single output of --input or --list; a job file "
                                                           "sets it in its [[output]] and [[collection]] tables");
    check_method_options(*cmd, o.method);
    if (job->count() == 0) check_method_values(o.method, "batch");
    if (const std::string why = jobs::worker_timeout_problem(o); !why.empty())
      throw CLI::ValidationError("--worker-timeout", why);
  });
  cmd->footer(
      "Run alone or as `mpirun -n N gimforge batch ...` / `srun --mpi=pmix gimforge batch ...`: rank 0 schedules\n"
      "(largest meshes first), the other ranks convert and commit one shard file per item; rank 0 journals every\n"
      "commit in ARCHIVE.work/journal.jsonl and finally merges the shards into ARCHIVE (written whole, then\n"
      "renamed). Killed at any moment, the same command with --resume finishes the job without redoing\n"
      "committed items. SIGTERM / SIGUSR1: stop dispatching, let running items finish, exit 4 (resumable; under\n"
      "mpirun send SIGUSR1: on SIGINT or SIGTERM mpirun ends the ranks itself, exit 1, still resumable). Exit 3\n"
      "when some items failed (listed with their reason in the archive). Each rank uses one thread unless -j is\n"
      "given. Layout of the archive: docs/archive.md; loading it: examples/load_archive.py.");
}

int dispatch(CLI::App& app, Commands& c, const GlobalOptions& g) {
  if (app.got_subcommand("info")) return run_info(c.info);
  if (app.got_subcommand("validate")) return run_validate(c.validate);
  if (app.got_subcommand("metrics")) {
    c.metrics.progress = !g.quiet;
    c.metrics.threads = g.threads;
    return run_metrics(c.metrics);
  }
  if (app.got_subcommand("convert")) {
    c.convert.progress = !g.quiet;
    c.convert.threads = g.threads;
    return run_convert(c.convert);
  }
  if (app.got_subcommand("batch")) {
    c.batch.progress = !g.quiet;
    if (g.threads > 0) c.batch.threads_per_rank = g.threads;
    return run_batch(c.batch);
  }
  if (app.got_subcommand("reconstruct")) return run_reconstruct(c.reconstruct);
  if (app.got_subcommand("compress")) return run_compress(c.compress);
  if (app.got_subcommand("decompress")) return run_decompress(c.decompress);
  if (app.got_subcommand("preview")) return run_preview(c.preview);
  if (app.got_subcommand("render")) return run_render(c.render);
  if (app.got_subcommand("ls")) return run_ls(c.ls);
  if (app.got_subcommand("convert-format")) return run_convert_format(c.convert_format);
  if (app.got_subcommand("synth")) {
    c.synth.progress = !g.quiet;
    return run_synth(c.synth);
  }
  return kExitUsage;
}

/// The first word of the command line where a command belongs, when it names none ("" otherwise): the
/// global options and their values are skipped.
std::string unknown_command(CLI::App& app, int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string_view word = argv[i];
    if (word == "-j" || word == "--threads" || word == "--log-level") {
      ++i;
      continue;
    }
    if (word.starts_with("-")) continue;
    for (const CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; }))
      if (sub->check_name(std::string(word))) return {};
    return std::string(word);
  }
  return {};
}

}  // namespace

/// Integer options read decimal only and within 64 bits (option_values.h: CLI11 reads strtoll's base 0, so a
/// `--size 0101` made a 65 x 65 image); a --name is never empty.
void require_decimal_integers(CLI::App& app) {
  for (CLI::Option* option : app.get_options()) {
    const std::string type = option->get_type_name();
    // transform(): before the option's own checks, whose range message would call "abc" or "0129" a value
    // out of range (and print double's range in 309 digits for a negative number).
    if (type == "FLOAT" || type.starts_with("FLOAT:")) {  // CLI11's ranges let "nan" through
      option->transform(CLI::Validator([](std::string& text) { return real_value_error(text); }, ""));
      continue;
    }
    const bool is_unsigned = type == "UINT" || type.starts_with("UINT:");
    if (!is_unsigned && type != "INT" && !type.starts_with("INT:")) continue;
    option->transform(CLI::Validator([is_unsigned](std::string& text) { return integer_value_error(text, is_unsigned); }, ""));
  }
  if (CLI::Option* name = app.get_option_no_throw("--name"); name != nullptr)
    name->check(CLI::Validator([](std::string& text) { return name_value_error(text); }, ""));
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) require_decimal_integers(*sub);
}

int main(int argc, char** argv) {
  // A write past the file-size limit (ulimit -f) then fails with EFBIG, reported as one line and cleaned up.
  std::signal(SIGXFSZ, SIG_IGN);
  CLI::App app{"gimforge: turn triangle meshes into regular surface representations (geometry images and\n"
               "relatives), measure their fidelity, and store them in HDF5 archives."};
  app.set_version_flag("--version", std::string("gimforge ") + kVersion);
  app.footer(kFooter);
  app.require_subcommand(1);
  app.fallthrough();  // the global options after the command too (`gimforge batch -j 1 ...`)
  app.failure_message(  // usage errors read as every other error: one line (exit code 2 tells them apart)
[](const CLI::App*, const CLI::Error& e) {
    std::string what = e.what();
    // CLI11's "Could not convert: --level = 4294967296": a decimal number beyond the option's type.
    if (constexpr std::string_view head = "Could not convert: "; what.starts_with(head))
      if (const std::size_t eq = what.find(" = ", head.size()); eq != std::string::npos)
        what = fmt::format("{}: '{}' is out of range", what.substr(head.size(), eq - head.size()), what.substr(eq + 3));
    return fmt::format("gimforge: error: {} (see --help)\n", what);
  });
  GlobalOptions global;
  Commands c;
  add_global_options(app, global);
  add_info(app, c.info);
  add_validate(app, c.validate);
  add_metrics(app, c.metrics);
  add_convert(app, c.convert);
  add_batch(app, c.batch);
  add_global_options(*app.get_subcommand("batch"), global);  // after `batch` too: it keeps its stray words
  add_reconstruct(app, c.reconstruct);
  add_compress(app, c.compress);
  add_decompress(app, c.decompress);
  add_preview(app, c.preview);
  add_render(app, c.render);
  add_ls(app, c.ls);
  add_convert_format(app, c.convert_format);
  add_synth(app, c.synth);
  require_decimal_integers(app);
  jobs::set_command_line(argc, argv);  // provenance: every item records it (quoted as a shell would need it)
  c.convert.command_line = jobs::command_line();
  c.batch.command_line = c.convert.command_line;
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // Under mpirun every rank parses the same command line: rank 0 says what is wrong, once.
    if (e.get_exit_code() != 0 && !mpi::may_be_rank_zero()) return kExitUsage;
    if (const std::string unknown = unknown_command(app, argc, argv); !unknown.empty()) {
      std::vector<std::string> names;
      for (const CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) names.push_back(sub->get_name());
      fmt::print(stderr, "gimforge: error: unknown command '{}' (commands: {}; see gimforge --help)\n", io::printable(unknown),
                 fmt::join(names, ", "));
      return kExitUsage;
    }
    const int code = app.exit(e);
    return code == 0 ? kExitOk : kExitUsage;
  }
  // The commands that only read an archive run in a child process: HDF5 itself crashes on some crafted
  // files, and such a crash must be one error line, not a signal (crash_guard.h).
  const std::string archive = app.got_subcommand("reconstruct") ? c.reconstruct.archive
                              : app.got_subcommand("compress")  ? c.compress.archive
                              : app.got_subcommand("decompress") ? c.decompress.archive
                              : app.got_subcommand("preview")   ? c.preview.archive
                              : app.got_subcommand("render")    ? c.render.archive
                              : app.got_subcommand("ls")        ? c.ls.archive
                                                                : std::string();
  // What an out-of-memory error is about: the file the command reads.
  const std::string subject = !archive.empty() ? archive : app.got_subcommand("convert") ? c.convert.mesh : std::string();
  return run_command(archive, subject, global, [&] { return dispatch(app, c, global); });
}

}  // namespace gimforge::cli
