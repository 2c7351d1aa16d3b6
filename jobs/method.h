#pragma once
/// \file method.h
/// The conversion methods, in one place: their name on the command line and in job files, the archive
/// group their results live in, their options (with the checks, the JSON form recorded in archives and
/// journals, and the default output name of a batch), and what each needs of its input mesh. Every command
/// that converts (convert, batch) and every command that reads results (reconstruct, preview, render) goes
/// through this file; jobs/pipeline.h runs a method.
#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <utility>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "io/representation.h"
#include "jobs/load_mesh.h"

namespace gimforge::jobs {

/// A regular representation gimforge converts meshes to.
enum class Method {
  Gim,     ///< geometry image (Gu, Gortler, Hoppe 2002): archive group /gim
  Sphere,  ///< spherical geometry image (Praun, Hoppe 2003): /spherical
  Relief,  ///< relief map on a cubic cell complex (Apaza, Andújar): /relief
  Mcgim,   ///< multi-chart geometry image (Sander, Wood, Gortler, Snyder, Hoppe 2003): /mcgim
};

/// Every method, in the order help texts and error messages list them.
inline constexpr std::array kMethods{Method::Gim, Method::Sphere, Method::Relief, Method::Mcgim};

/// The method's name on the command line, in job files and in the archive's `method` attribute:
/// "gim", "sphere", "relief", "mcgim".
[[nodiscard]] std::string_view method_name(Method method);

/// "gim, sphere, relief, mcgim": for help texts and messages.
[[nodiscard]] std::string method_list();

/// Parses a method name. Throws InvalidInput "unknown method 'X' (available: gim, sphere, relief, mcgim)".
[[nodiscard]] Method parse_method(std::string_view text);

/// Where the method's results live in the archive (`group`: "gim", "spherical", "relief", "mcgim") and what messages
/// call them ("geometry image", ...).
[[nodiscard]] const io::RepresentationKind& representation(Method method);

/// What the method needs of its input: gim and sphere need a consistently oriented 2-manifold (boundaries
/// allowed; the kernels check genus and components); mcgim (whose kernel cuts non-manifold edges and
/// orientation conflicts) and relief take any triangle soup.
[[nodiscard]] LoadPolicy load_policy(Method method, bool warn);

/// Largest values the options accept.
inline constexpr std::uint32_t kMaxSphereN = 4096;       ///< sphere --n: a (2·4096+1)² octahedral image
inline constexpr std::uint32_t kMaxReliefGrid = 1024;    ///< relief --grid and --max-grid
inline constexpr std::uint32_t kMaxReliefTexture = 1024; ///< relief --texture
inline constexpr int kMaxAugmentations = 64;             ///< gim --max-augmentations
/// --metric-samples (per direction): about 50 bytes per pair of samples, so 6.7 GB at the bound.
inline constexpr std::size_t kMaxMetricSamples = std::size_t{1} << 27;
inline constexpr std::uint32_t kMaxMcgimSamples = 1u << 24;  ///< mcgim --samples (a 4096² rectangle)
inline constexpr std::uint32_t kMaxMcgimCharts = 4096;      ///< mcgim --charts
inline constexpr std::size_t kMinProxyFaces = 1000;         ///< --proxy-faces
inline constexpr std::size_t kAutoProxyInputFaces = 1'000'000;  ///< --proxy-faces auto: larger inputs get a proxy
inline constexpr std::uint32_t kMaxProxyBricks = 64;         ///< --proxy-bricks
inline constexpr std::uint32_t kMaxAdaptRounds = 1000;       ///< gim --adapt-rounds
inline constexpr double kMaxRoiGain = 64.0;                  ///< --roi-gain
inline constexpr std::uint32_t kMaxRoiSize = 513;            ///< image width with --roi (enhancement solves the whole grid)

/// A method and its options. Each method reads only its own fields; the others keep their defaults.
struct MethodOptions {
  Method method{Method::Gim};
  // gim
  std::uint32_t size{257};          ///< n×n image, n = 64k + 1
  std::uint32_t normal_size{512};   ///< normal-map resolution (0: none)
  int max_augmentations{6};         ///< cut-augmentation iterations
  std::string sampling{"uniform"};  ///< "uniform" or "adaptive" (kernels/adaptive: strips, then Hausdorff-driven moves)
  std::uint32_t adapt_rounds{12};   ///< adaptive sampling: at most this many adjustment rounds (0..kMaxAdaptRounds)
  std::string adapt_start{"auto"};  ///< adaptive sampling: start grid "auto", "uniform" or "strips"
  /// adaptive sampling: region of interest (jobs/roi.h): "" (none), "auto[:F]", "box:X0,Y0,Z0,X1,Y1,Z1",
  /// "vertices:FILE", "color:RRGGBB", "scalar:NAME[>T]", "mask:PNG"
  std::string roi{};
  double roi_gain{4.0};             ///< the ROI gets roi_gain × its samples of the start grid (1..kMaxRoiGain)
  // sphere
  std::string domain{"octa"};       ///< octa, tetra, cube or flat-octa
  std::uint32_t n{128};             ///< tessellation number, 1..kMaxSphereN
  // relief
  std::string grid{"auto"};         ///< cells per axis (1..kMaxReliefGrid) or "auto" (occlusion-driven, §3.3.3)
  std::uint32_t texture{64};        ///< texels per side of every domain face (2..kMaxReliefTexture)
  std::uint32_t max_grid{32};       ///< --grid auto: largest N tried
  double occlusion_threshold{0.05}; ///< --grid auto: keep N once hidden / all samples <= this
  // mcgim
  std::uint32_t samples{65536};     ///< bound on the rectangle's area W·H (64..kMaxMcgimSamples)
  std::string charts{"auto"};       ///< charts requested (1..kMaxMcgimCharts) or "auto" (a short search, §5 Fig. 13)
  bool optimize{false};             ///< geometry-image optimization (Sander et al. 2003 §4.6): gim, sphere, mcgim
  // gim, sphere, mcgim: huge inputs through a decimated proxy (issue #17; jobs/proxy.h)
  std::string proxy_faces{"auto"};  ///< "auto", "off" or a face count in [kMinProxyFaces, 2^31]
  /// Bricks the input is decimated in before the proxy is finished whole (kernels/scan/decimate.h), 1 to
  /// kMaxProxyBricks; 0: jobs::proxy_bricks of the sizes. In a batch each brick is a task of its own.
  std::uint32_t proxy_bricks{0};
  /// gim, sphere, mcgim: "off", or "R" / "R:C": the proxy is a closed one-piece wrap of the input
  /// (kernels/scan/wrap.h) at R voxels along its longest side with a closing of C voxels (default 1)
  std::string wrap{"off"};
  // gim, sphere in a batch (`batch --codec C --rate B`, jobs/compress.h): every item stored compressed
  std::string codec{};              ///< "" (float32 images), "auto", "j2k", "wavelet", "quant12" or "quant16"
  std::uint64_t rate{0};            ///< stored bytes per item (j2k, wavelet, auto; at least 1024)

  /// Throws InvalidInput "<what>: <option> <value> <why>" for a value the method cannot use; `what` names
  /// the caller's context (e.g. "output 'gim_257'" or "convert").
  void check(std::string_view what) const;
  /// The method and its own options, e.g. {"method": "gim", "size": 257, "normal_size": 512,
  /// "max_augmentations": 6}: recorded in archives (creation_parameters) and batch journals.
  [[nodiscard]] nlohmann::json to_json() const;
  /// The inverse of to_json (missing fields keep their defaults). Throws InvalidInput for an unknown method.
  [[nodiscard]] static MethodOptions from_json(const nlohmann::json& j);
  /// True for --sampling adaptive.
  [[nodiscard]] bool adaptive() const { return sampling == "adaptive"; }
  /// The default name of a batch output: "gim_257" ("gim_257_adaptive"), "sphere_octa_128", "relief_auto_64" / "relief_16_64",
  /// "mcgim_65536_auto" ("mcgim_65536_auto_opt" when optimized).
  [[nodiscard]] std::string default_output_name() const;
  /// The string attributes a batch output group records: method and its resolution options.
  [[nodiscard]] std::map<std::string, std::string> attributes() const;
  /// --grid as a number: 0 for "auto". Throws InvalidInput when it is neither.
  [[nodiscard]] std::uint32_t relief_grid() const;
  /// --charts as a number: 0 for "auto". Throws InvalidInput when it is neither.
  [[nodiscard]] std::uint32_t mcgim_charts() const;
  /// Samples of the image the method makes: gim size², sphere the domain image's, mcgim `samples`; 0 for
  /// relief.
  [[nodiscard]] std::size_t image_samples() const;
  /// How many faces the proxy of an input of `input_faces` faces gets, 0 for no proxy: --proxy-faces F gives
  /// F (when the input has more), "off" and relief none, "auto" image_samples()/4 for gim and sphere and
  /// image_samples() for mcgim (at least kMinProxyFaces)
  /// for inputs of more than kAutoProxyInputFaces faces and more than 4 faces per image sample — where
  /// parametrizing every face would cost minutes and gigabytes for detail the image cannot hold.
  [[nodiscard]] std::size_t proxy_target(std::size_t input_faces) const;
  /// --wrap as (resolution, closing); nullopt for "off". Throws InvalidInput for any other text.
  [[nodiscard]] std::optional<std::pair<std::uint32_t, std::uint32_t>> wrap_voxels() const;
  /// Faces of the proxy made from the wrap: --proxy-faces F, else what "auto" gives a huge input.
  [[nodiscard]] std::size_t wrap_proxy_target() const;
};

/// load_policy of the method, taking any triangles when it converts through a wrap (--wrap).
[[nodiscard]] LoadPolicy load_policy(const MethodOptions& method, bool warn);

}  // namespace gimforge::jobs
