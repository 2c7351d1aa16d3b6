#include "jobs/error_naming.h"

#include <algorithm>
#include <cmath>
#include <span>
#include <string_view>
#include <utility>

#include <fmt/format.h>

#include "kernels/core/errors.h"
#include "kernels/core/topology.h"

namespace gimforge::jobs {
namespace {

/// The wrap a refusal suggests: 512 voxels along the longest side, as docs/cli.md's examples.
constexpr std::uint32_t kAdvisedResolution = 512;
/// The largest closing --wrap takes (MethodOptions::wrap_voxels).
constexpr std::uint32_t kMaxClosing = 16;

using Hints = std::span<const std::pair<std::string_view, std::string_view>>;

/// `text` with the first occurrence of every `from` replaced by its `to`, formatted with {wrap} and {hole}.
std::string apply(std::string text, Hints hints, const std::string& wrap, const std::string& hole) {
  for (const auto& [from, to] : hints)
    if (const auto at = text.find(from); at != std::string::npos)
      text.replace(at, from.size(), fmt::format(fmt::runtime(to), fmt::arg("wrap", wrap), fmt::arg("hole", hole)));
  return text;
}

/// The kernels' wording, re-worded for the command line: no internal function names, and the methods by their
/// option (what works for several components is --method mcgim or --method relief).
constexpr std::pair<std::string_view, std::string_view> kRewrites[] = {
    {"sample_surface: ", ""},
    {"wrap: ", ""},  // said by the prefix "its wrap (--wrap …)"
    {"the mesh has 0 connected components; a geometry image needs one connected surface (use the multi-chart "
     "method for several components)",
     "no faces left after repair"},
    {"use the multi-chart method for several components",
     "--method mcgim (multi-chart geometry image) or --method relief converts meshes of several components"},
    {"for several components multi-chart geometry images", "for several components --method mcgim or --method relief"},
    {"for another genus use geometry images or multi-chart geometry images",
     "--method gim or --method mcgim converts another genus"},
    {"no cut found whose parametrization is bijective in floating point",
     "no cut found whose parametrization is bijective in floating point (the geometry image cannot be made; "
     "--method mcgim converts any 2-manifold, --method relief any mesh)"},
};
// Without a wrap, a wrap is what lets a single-chart method take the mesh — where one can seal its holes;
// with one, its closing.
constexpr std::pair<std::string_view, std::string_view> kWrapHints[] = {
    {"converts meshes of several components", "converts meshes of several components, {wrap} a closed one-piece wrap of it"},
    {"for several components --method mcgim or --method relief",
     "for several components --method mcgim or --method relief, or {wrap} for a closed one-piece wrap"},
    {"(fill them first)", "(fill them first, or {wrap} converts a closed one-piece wrap of the mesh)"},
    {" grid units", " grid units (too many handles and holes for one square: {wrap} converts a closed wrap "
                    "that seals the small ones, --method mcgim any 2-manifold)"}};
constexpr std::pair<std::string_view, std::string_view> kUnsealableHints[] = {
    {"(fill them first)", "(fill them first, or --method mcgim or --method relief converts it as it is; its widest "
                          "hole, {hole})"},
    {" grid units", " grid units (too many handles and holes for one square: --method mcgim converts any 2-manifold; "
                    "its widest hole, {hole})"}};
constexpr std::pair<std::string_view, std::string_view> kWrappedHints[] = {
    {" grid units", " grid units (too many handles for one square: a larger closing C in --wrap R:C seals more, "
                    "--method mcgim converts any genus)"}};

}  // namespace

WrapAdvice wrap_advice(MeshView mesh) {
  WrapAdvice advice;
  advice.widest_hole = widest_hole(mesh);
  const BoundingBox box = bounding_box(mesh);
  const double voxel = box.empty() ? 0.0 : (box.max - box.min).maxCoeff() / kAdvisedResolution;
  advice.sealable = 2.0 * kMaxClosing * voxel;
  // A closing of C voxels seals a hole up to about 2C voxels across (scan/wrap.h; measured on a sphere with a
  // round hole: 12 voxels wide sealed at C = 4, not 3; 20 at C = 8, not 7; 32 at C = 14).
  const double closing = voxel > 0.0 ? std::max(1.0, std::ceil(advice.widest_hole / (2.0 * voxel))) : 1.0;
  if (closing <= 1.0)
    advice.option = fmt::format("--wrap {}", kAdvisedResolution);
  else if (closing <= kMaxClosing)
    advice.option = fmt::format("--wrap {}:{}", kAdvisedResolution, static_cast<std::uint32_t>(closing));
  return advice;
}

std::string wrap_clause(const TriMesh* mesh) {
  const std::string option = mesh ? wrap_advice(*mesh).option : fmt::format("--wrap {}", kAdvisedResolution);
  return option.empty() ? std::string{} : fmt::format(", {} converts a closed one-piece wrap of it", option);
}

std::string coarse_relief_hint(double cell_size, std::uint32_t texture) {
  return fmt::format("; its texels are {:.3g} across, coarser than the surface: a larger --texture (up to 1024) or "
                     "--grid N (up to 1024) makes them finer", cell_size / texture);
}

void name_errors(const std::string& source, const std::function<void()>& f, const std::string& wrap,
                 const TriMesh* input) {
  if (source.empty()) return f();
  const auto reworded = [&](const char* what) {
    std::string text = apply(what, kRewrites, {}, {});
    if (!wrap.empty())
      return fmt::format("{}: its wrap (--wrap {}): {}", source, wrap, apply(text, kWrappedHints, {}, {}));
    // The mesh's holes are measured (O(F log F)) only for a refusal a wrap could get around.
    if (std::ranges::none_of(kWrapHints, [&](const auto& hint) { return text.find(hint.first) != std::string::npos; }))
      return fmt::format("{}: {}", source, text);
    const WrapAdvice advice = input ? wrap_advice(*input) : WrapAdvice{fmt::format("--wrap {}", kAdvisedResolution)};
    text = advice.option.empty()
               ? apply(text, kUnsealableHints, {},
                       fmt::format("{:.3g} across, is wider than --wrap {}:{} seals ({:.3g}; a lower R seals wider "
                                   "holes, with a coarser wrap)",
                                   advice.widest_hole, kAdvisedResolution, kMaxClosing, advice.sealable))
               : apply(text, kWrapHints, advice.option, {});
    return fmt::format("{}: {}", source, text);
  };
  try {
    f();
  } catch (const TopologyError& e) {
    throw TopologyError(reworded(e.what()));
  } catch (const InvalidInput& e) {
    throw InvalidInput(reworded(e.what()));
  } catch (const Cancelled& e) {
    throw Cancelled(reworded(e.what()));
  } catch (const NumericalError& e) {
    throw NumericalError(reworded(e.what()));
  } catch (const LibraryError& e) {
    throw LibraryError(reworded(e.what()));
  }
}

}  // namespace gimforge::jobs
