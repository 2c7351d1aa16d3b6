#include "jobs/method.h"

#include <algorithm>
#include <charconv>
#include <filesystem>
#include <limits>

#include <fmt/format.h>

#include "io/gim_archive.h"
#include "jobs/roi.h"
#include "io/mcgim_archive.h"
#include "io/relief_archive.h"
#include "io/sphere_archive.h"
#include "kernels/core/errors.h"
#include "kernels/sphere/spherical_domain.h"

namespace gimforge::jobs {

std::string_view method_name(Method method) {
  switch (method) {
    case Method::Gim: return "gim";
    case Method::Sphere: return "sphere";
    case Method::Relief: return "relief";
    case Method::Mcgim: return "mcgim";
  }
  return "?";
}

std::string method_list() {
  std::string out;
  for (const Method m : kMethods) out += (out.empty() ? "" : ", ") + std::string(method_name(m));
  return out;
}

Method parse_method(std::string_view text) {
  for (const Method m : kMethods)
    if (method_name(m) == text) return m;
  throw InvalidInput(fmt::format("unknown method '{}' (available: {})", text, method_list()));
}

const io::RepresentationKind& representation(Method method) {
  switch (method) {
    case Method::Gim: return io::kGeometryImages;
    case Method::Sphere: return io::kSphericalImages;
    case Method::Relief: return io::kReliefMaps;
    case Method::Mcgim: return io::kMultiChartImages;
  }
  return io::kGeometryImages;
}

LoadPolicy load_policy(Method method, bool warn) {
  // Relief maps take any triangle soup: several components, boundaries, non-manifold edges (the inside
  // test falls back to parity votes when the mesh is not watertight).
  // Multi-chart images take them too: the kernel cuts non-manifold edges and orientation conflicts into
  // boundaries, reorients faces and splits pinched vertices into one vertex per fan (manifold_cut.h).
  const bool single_chart = method == Method::Gim || method == Method::Sphere;
  return {.repair = true,
          .require_manifold = single_chart,
          .require_oriented = single_chart,
          .warn = warn,
          .refusal_hint = single_chart ? "; --method mcgim cuts such a mesh into a 2-manifold, --method relief takes any "
                                         "mesh"
                                       : "",
          .suggest_wrap = single_chart};
}

LoadPolicy load_policy(const MethodOptions& method, bool warn) {
  LoadPolicy policy = load_policy(method.method, warn);
  if (method.wrap_voxels()) {  // the wrap takes any triangles
    policy.require_manifold = policy.require_oriented = false;
    policy.refusal_hint = "";
    policy.suggest_wrap = false;
  }
  return policy;
}

namespace {

/// "auto" (0) or a whole number in [1, max]; InvalidInput "--OPTION 'TEXT' is neither 'auto' nor a number of
/// WHAT in [1, MAX]" otherwise.
std::uint32_t auto_or_count(const std::string& text, std::uint32_t max, std::string_view option, std::string_view what) {
  if (text == "auto") return 0;
  std::uint32_t value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc{} || end != text.data() + text.size() || value < 1 || value > max || text.front() == '0')
    throw InvalidInput(fmt::format("{} '{}' is neither 'auto' nor a number of {} in [1, {}]", option, text, what, max));
  return value;
}

}  // namespace

std::uint32_t MethodOptions::relief_grid() const {
  return auto_or_count(grid, kMaxReliefGrid, "--grid", "cells per axis");
}

std::uint32_t MethodOptions::mcgim_charts() const { return auto_or_count(charts, kMaxMcgimCharts, "--charts", "charts"); }

std::size_t MethodOptions::image_samples() const {
  switch (method) {
    case Method::Gim: return std::size_t{size} * size;
    case Method::Sphere: return DomainImage(parse_spherical_domain(domain), n).num_samples();
    case Method::Mcgim: return samples;
    case Method::Relief: return 0;
  }
  return 0;
}

std::size_t MethodOptions::proxy_target(std::size_t input_faces) const {
  if (method == Method::Relief || proxy_faces == "off") return 0;
  if (proxy_faces == "auto") {
    const std::size_t image = image_samples();
    if (input_faces <= kAutoProxyInputFaces || input_faces <= 4 * image) return 0;
    // A multi-chart image spends its samples on many charts (the dragon: ~1,100) and their gaps: its proxy
    // keeps one face per sample (a quarter of that cost the dragon 14 dB; BENCHMARKS.md "Proxies").
    return std::max(kMinProxyFaces, method == Method::Mcgim ? image : image / 4);
  }
  std::size_t value = 0;
  const auto [end, ec] = std::from_chars(proxy_faces.data(), proxy_faces.data() + proxy_faces.size(), value);
  if (ec != std::errc{} || end != proxy_faces.data() + proxy_faces.size() || proxy_faces.front() == '0' || value < kMinProxyFaces ||
      value > (std::size_t{1} << 31))
    throw InvalidInput(fmt::format("--proxy-faces '{}' is neither 'auto', 'off' nor a number of faces in [{}, {}]",
                                   proxy_faces, kMinProxyFaces, std::size_t{1} << 31));
  return value < input_faces ? value : 0;
}

std::optional<std::pair<std::uint32_t, std::uint32_t>> MethodOptions::wrap_voxels() const {
  if (wrap == "off") return std::nullopt;
  const auto number = [&](std::string_view text, std::uint32_t lo, std::uint32_t hi, std::uint32_t& value) {
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    return ec == std::errc{} && end == text.data() + text.size() && (text.front() != '0' || text == "0") && value >= lo &&
           value <= hi;  // from_chars fails on empty text; no leading zeros
  };
  const std::string_view text = wrap;
  const auto colon = text.find(':');
  std::uint32_t resolution = 0, closing = 1;
  if (!number(text.substr(0, colon), 16, 2048, resolution) ||
      (colon != std::string_view::npos && !number(text.substr(colon + 1), 0, 16, closing)))
    throw InvalidInput(fmt::format("--wrap '{}' is neither 'off' nor R or R:C (R voxels along the longest side in "
                                   "[16, 2048], a closing of C voxels in [0, 16])",
                                   wrap));
  return std::make_pair(resolution, closing);
}

std::size_t MethodOptions::wrap_proxy_target() const {
  if (proxy_faces != "auto" && proxy_faces != "off") return proxy_target(std::numeric_limits<std::size_t>::max());
  return std::max(kMinProxyFaces, method == Method::Mcgim ? image_samples() : image_samples() / 4);
}

void MethodOptions::check(std::string_view what) const {
  auto fail = [&](const std::string& cause) { throw InvalidInput(fmt::format("{}: {}", what, cause)); };
  if (sampling != "uniform" && sampling != "adaptive")
    fail(fmt::format("unknown sampling '{}' (choose uniform or adaptive)", sampling));
  if (adapt_start != "auto" && adapt_start != "uniform" && adapt_start != "strips")
    fail(fmt::format("unknown adaptive start '{}' (choose auto, uniform or strips)", adapt_start));
  if (adaptive() && method != Method::Gim && method != Method::Sphere)
    fail(fmt::format("--sampling adaptive is built for --method gim and sphere (this is --method {}); the other "
                     "methods sample their domains uniformly",
                     method_name(method)));
  if (adaptive() && method == Method::Sphere && n < 2)
    fail(fmt::format("--sampling adaptive of a spherical image needs --n 2 or more (this is {})", n));
  if (adaptive() && method == Method::Sphere && domain != "flat-octa")
    fail(fmt::format("--sampling adaptive of a spherical image needs --domain flat-octa (this is {}): its image is a "
                     "square folded at its side midpoints and split along shorter diagonals, as the adjustment "
                     "measures it (docs/adaptive.md)",
                     domain));
  if (adaptive() && adapt_rounds > kMaxAdaptRounds)
    fail(fmt::format("adapt_rounds {} is outside 0..{}", adapt_rounds, kMaxAdaptRounds));
  if (!roi.empty() && method != Method::Gim && method != Method::Sphere)
    fail(fmt::format("--roi is built for --method gim and sphere (this is --method {})", method_name(method)));
  if (!roi.empty() && !adaptive())
    fail(fmt::format("--roi {} needs --sampling adaptive (the ROI gets its samples by moving them)", roi));
  if (!roi.empty()) {
    RoiSpec spec;
    try {
      spec = parse_roi_spec(roi);
    } catch (const InvalidInput& e) {
      fail(e.what());
    }
    // A missing file fails here, once, rather than in every item of a batch (each retried).
    if (std::error_code ec; (spec.kind == RoiSpec::Kind::Vertices || spec.kind == RoiSpec::Kind::Mask) &&
                            !std::filesystem::is_regular_file(spec.file, ec))
      fail(fmt::format("--roi {}: {}: {} ({} was expected)", roi, spec.file,
                       std::filesystem::exists(spec.file, ec) ? "not a regular file (a directory, pipe or device)"
                                                              : "no such file",
                       spec.kind == RoiSpec::Kind::Mask ? "a PNG mask" : "a list of vertex indices"));
    const std::uint64_t width = method == Method::Gim ? std::uint64_t{size} : 2 * std::uint64_t{n} + 1;
    if (width > kMaxRoiSize)
      fail(fmt::format("--roi is built for images up to {0}×{0} samples (this is {1}×{1}): enhancement solves a sparse "
                       "system of every sample, about 3 minutes and 750 MiB at 513, several times that beyond",
                       kMaxRoiSize, width));
  }
  if (!(roi_gain >= 1.0 && roi_gain <= kMaxRoiGain))
    fail(fmt::format("--roi-gain {} is outside 1..{}", roi_gain, kMaxRoiGain));
  if (adaptive() && optimize)
    fail("--sampling adaptive and --optimize both move the samples (onto the surface by the Hausdorff "
         "distance, off it by the fit): choose one");
  if (optimize && method == Method::Relief)
    fail("--optimize (geometry-image optimization) is for the image methods gim, sphere and mcgim; a relief map "
         "has no geometry image to fit");
  if (proxy_faces != "auto" && proxy_faces != "off") {
    if (method == Method::Relief)
      fail("--proxy-faces is for the image methods gim, sphere and mcgim; a relief map samples every face");
    try {
      (void)proxy_target(0);
    } catch (const InvalidInput& e) {
      fail(e.what());
    }
  }
  if (proxy_bricks > kMaxProxyBricks) fail(fmt::format("--proxy-bricks {} is outside 0..{}", proxy_bricks, kMaxProxyBricks));
  if (proxy_bricks != 0 && method == Method::Relief)
    fail("--proxy-bricks is for the image methods gim, sphere and mcgim; a relief map has no proxy");
  std::optional<std::pair<std::uint32_t, std::uint32_t>> wrapped;
  try {
    wrapped = wrap_voxels();
  } catch (const InvalidInput& e) {
    fail(e.what());
  }
  if (wrapped && method == Method::Relief)
    fail("--wrap is for the image methods gim, sphere and mcgim; a relief map takes any mesh as it is");
  if (wrapped && proxy_faces == "off") fail("--wrap converts through a proxy: it cannot be combined with --proxy-faces off");
  if (proxy_bricks != 0 && proxy_faces == "off")
    fail(fmt::format("--proxy-bricks {} has no effect with --proxy-faces off (no proxy is made)", proxy_bricks));
  if (!codec.empty()) {
    if (method == Method::Relief)
      fail("--codec is for the image methods gim, sphere and mcgim (a relief map is not coded)");
    if (codec != "auto" && codec != "j2k" && codec != "wavelet" && codec != "quant12" && codec != "quant16" &&
        codec != "j2k-roi")
      fail(fmt::format("unknown codec '{}' (auto, j2k, wavelet, quant12, quant16, j2k-roi)", codec));
    if (codec == "j2k-roi" && (method != Method::Gim || roi.empty()))
      fail("--codec j2k-roi codes the region of interest of geometry images: it needs --method gim --sampling "
           "adaptive --roi SPEC");
    const bool quant = codec == "quant12" || codec == "quant16";
    if (quant && rate != 0) fail(fmt::format("--codec {} quantizes without a rate: drop --rate", codec));
    if (!quant && rate == 0) fail(fmt::format("--codec {} needs --rate B, the stored bytes per item (at least 1024)", codec));
    if (!quant && rate < 1024) fail(fmt::format("--rate {} is below 1024 (the stored bytes per item, --codec {})", rate, codec));
    if (codec == "wavelet" && method == Method::Sphere && domain != "octa" && domain != "flat-octa")
      fail(fmt::format("--codec wavelet takes octahedral images (octa, flat-octa), not {}; use j2k or auto", domain));
    if (codec == "wavelet" && method == Method::Mcgim)
      fail("--codec wavelet takes square images (gim, octa, flat-octa), not a multi-chart rectangle; use j2k or auto");
  } else if (rate != 0) {
    fail("--rate needs --codec");
  }
  switch (method) {
    case Method::Gim:
      if (size < 65 || (size - 1) % 64 != 0) fail(fmt::format("gim size {}: n - 1 must be a multiple of 64 (65, 129, 257, ...)", size));
      if (normal_size > 8192) fail(fmt::format("gim normal size {} is outside 0..8192", normal_size));
      if (max_augmentations < 0 || max_augmentations > kMaxAugmentations)
        fail(fmt::format("gim max_augmentations {} is outside 0..{}", max_augmentations, kMaxAugmentations));
      break;
    case Method::Sphere:
      try {
        (void)parse_spherical_domain(domain);
      } catch (const InvalidInput&) {
        fail(fmt::format("unknown spherical domain '{}' (choose octa, tetra, cube or flat-octa)", domain));
      }
      if (n < 1 || n > kMaxSphereN) fail(fmt::format("sphere n = {} is outside 1..{}", n, kMaxSphereN));
      break;
    case Method::Relief:
      try {
        (void)relief_grid();
      } catch (const InvalidInput& e) {
        fail(e.what());
      }
      if (texture < 2 || texture > kMaxReliefTexture)
        fail(fmt::format("relief texture {} is outside 2..{}", texture, kMaxReliefTexture));
      if (max_grid < 1 || max_grid > kMaxReliefGrid)
        fail(fmt::format("relief max_grid {} is outside 1..{}", max_grid, kMaxReliefGrid));
      if (!(occlusion_threshold >= 0.0 && occlusion_threshold <= 1.0))
        fail(fmt::format("relief occlusion_threshold {} is outside 0..1", occlusion_threshold));
      break;
    case Method::Mcgim:
      try {
        (void)mcgim_charts();
      } catch (const InvalidInput& e) {
        fail(e.what());
      }
      if (samples < 64 || samples > kMaxMcgimSamples)
        fail(fmt::format("mcgim samples {} is outside 64..{}", samples, kMaxMcgimSamples));
      break;
  }
}

nlohmann::json MethodOptions::to_json() const {
  nlohmann::json j = {{"method", method_name(method)}};
  // Absent when "auto" (the default): earlier records stay as they were.
  if (proxy_faces != "auto" && method != Method::Relief) j["proxy_faces"] = proxy_faces;
  if (proxy_bricks != 0 && method != Method::Relief) j["proxy_bricks"] = proxy_bricks;
  if (wrap != "off" && method != Method::Relief) j["wrap"] = wrap;  // absent when off: records stay as they were
  if (!codec.empty()) j.update({{"codec", codec}, {"rate", rate}});
  switch (method) {
    case Method::Gim:
      j.update({{"size", size}, {"normal_size", normal_size}, {"max_augmentations", max_augmentations}});
      if (optimize) j["optimize"] = true;  // absent when off: earlier records stay as they were
      if (adaptive()) j.update({{"sampling", sampling}, {"adapt_rounds", adapt_rounds}, {"adapt_start", adapt_start}});
      if (!roi.empty()) j.update({{"roi", roi}, {"roi_gain", roi_gain}});  // absent without: records stay as they were
      break;
    case Method::Sphere:
      j.update({{"domain", domain}, {"n", n}});
      if (optimize) j["optimize"] = true;
      if (adaptive()) j.update({{"sampling", sampling}, {"adapt_rounds", adapt_rounds}, {"adapt_start", adapt_start}});
      if (!roi.empty()) j.update({{"roi", roi}, {"roi_gain", roi_gain}});
      break;
    case Method::Mcgim: j.update({{"samples", samples}, {"charts", charts}, {"optimize", optimize}}); break;
    case Method::Relief:
      j.update({{"grid", grid}, {"texture", texture}, {"max_grid", max_grid}, {"occlusion_threshold", occlusion_threshold}});
      break;
  }
  return j;
}

MethodOptions MethodOptions::from_json(const nlohmann::json& j) {
  MethodOptions o;
  o.method = parse_method(j.at("method").get<std::string>());
  auto take = [&j](const char* key, auto& field) {
    if (j.contains(key)) field = j.at(key).get<std::decay_t<decltype(field)>>();
  };
  take("size", o.size);
  take("normal_size", o.normal_size);
  take("max_augmentations", o.max_augmentations);
  take("sampling", o.sampling);
  take("adapt_rounds", o.adapt_rounds);
  take("adapt_start", o.adapt_start);
  take("roi", o.roi);
  take("roi_gain", o.roi_gain);
  take("domain", o.domain);
  take("n", o.n);
  take("grid", o.grid);
  take("texture", o.texture);
  take("max_grid", o.max_grid);
  take("occlusion_threshold", o.occlusion_threshold);
  take("samples", o.samples);
  take("charts", o.charts);
  take("optimize", o.optimize);
  take("proxy_faces", o.proxy_faces);
  take("proxy_bricks", o.proxy_bricks);
  take("wrap", o.wrap);
  take("codec", o.codec);
  take("rate", o.rate);
  return o;
}

std::string MethodOptions::default_output_name() const {
  const std::string opt = std::string(optimize ? "_opt" : "") + (wrap == "off" ? "" : "_wrap") + (codec.empty() ? "" : "_" + codec) +
                          (rate == 0 || codec.empty() ? "" : std::to_string(rate));
  switch (method) {
    case Method::Gim: return fmt::format("gim_{}{}{}{}", size, adaptive() ? "_adaptive" : "", roi.empty() ? "" : "_roi", opt);
    case Method::Sphere:
      return fmt::format("sphere_{}_{}{}{}{}", domain, n, adaptive() ? "_adaptive" : "", roi.empty() ? "" : "_roi", opt);
    case Method::Relief: return fmt::format("relief_{}_{}", grid, texture);
    case Method::Mcgim: return fmt::format("mcgim_{}_{}{}", samples, charts, opt);
  }
  return {};
}

std::map<std::string, std::string> MethodOptions::attributes() const {
  std::map<std::string, std::string> a{{"method", std::string(method_name(method))}};
  switch (method) {
    case Method::Gim:
      a["size"] = std::to_string(size);
      if (adaptive()) a["sampling"] = sampling;
      if (!roi.empty()) a["roi"] = roi;
      break;
    case Method::Sphere:
      a["domain"] = domain, a["n"] = std::to_string(n);
      if (adaptive()) a["sampling"] = sampling;
      if (!roi.empty()) a["roi"] = roi;
      break;
    case Method::Relief: a["grid"] = grid, a["texture"] = std::to_string(texture); break;
    case Method::Mcgim: a["samples"] = std::to_string(samples), a["charts"] = charts; break;
  }
  if (optimize) a["optimize"] = "true";
  if (!codec.empty()) a["codec"] = codec;
  if (rate != 0) a["rate"] = std::to_string(rate);
  return a;
}

}  // namespace gimforge::jobs
