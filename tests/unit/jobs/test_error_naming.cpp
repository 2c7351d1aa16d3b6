// How a refusal reaches the command line: named by its input, worded by option, and suggesting a wrap only
// where a wrap can seal the mesh's holes (a suggestion that then fails is worse than none).
#include "jobs/error_naming.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "jobs/pipeline.h"
#include "kernels/core/embree_device.h"
#include "kernels/core/errors.h"
#include "kernels/core/procedural.h"
#include "tests/unit/test_support.h"

namespace gimforge::jobs {
namespace {

std::string refusal(const std::function<void()>& f, const std::string& wrap = {}, const TriMesh* input = nullptr) {
  try {
    name_errors("in.ply", f, wrap, input);
  } catch (const TopologyError& e) {
    return e.what();
  }
  return "(no error)";
}

const auto kTooManyPaths = [] { throw TopologyError("the cut has 858 cut-paths but the square perimeter only 256 grid units"); };

TEST(ErrorNaming, AWrapIsSuggestedOnlyWhereItSealsTheHoles) {
  // Closed: the default wrap.
  const TriMesh closed = make_slab_with_holes(3, 2);
  EXPECT_EQ(wrap_advice(closed).option, "--wrap 512");
  EXPECT_NE(refusal(kTooManyPaths, {}, &closed).find("--wrap 512 converts a closed wrap"), std::string::npos);
  // A hole 1/10 of the longest side wide: 51 voxels at 512, more than the largest closing (16) seals.
  const TriMesh open_slab = concatenate(make_slab_with_holes(0, 10), make_grid(10, 10, 3.0));  // a 10 × 30 × 1 box, a 3 × 3 sheet
  EXPECT_EQ(wrap_advice(open_slab).option, "");
  const std::string text = refusal(kTooManyPaths, {}, &open_slab);
  EXPECT_EQ(text.find("--wrap 512 "), std::string::npos) << text;
  EXPECT_NE(text.find("in.ply: the cut has 858 cut-paths"), std::string::npos) << text;
  EXPECT_NE(text.find("--method mcgim converts any 2-manifold; its widest hole, 3 across, is wider than --wrap 512:16 seals (1.88; a lower R seals wider holes, with a coarser wrap)"),
            std::string::npos)
      << text;
  // A hole of 1/64 of the longest side (8 voxels at 512): a closing of 4.
  TriMesh sheet = make_grid(10, 10, 30.0 / 64.0);
  const TriMesh small_hole = concatenate(make_slab_with_holes(0, 10), sheet);
  EXPECT_EQ(wrap_advice(small_hole).option, "--wrap 512:4");
  EXPECT_NE(refusal(kTooManyPaths, {}, &small_hole).find("--wrap 512:4 converts a closed wrap"), std::string::npos);
  // Without the mesh (a scan spread over ranks): the default; on a wrap: its closing, never --wrap again.
  EXPECT_NE(refusal(kTooManyPaths).find("--wrap 512 converts"), std::string::npos);
  const std::string wrapped = refusal(kTooManyPaths, "512", &open_slab);
  EXPECT_NE(wrapped.find("in.ply: its wrap (--wrap 512): the cut has"), std::string::npos) << wrapped;
  EXPECT_NE(wrapped.find("a larger closing C in --wrap R:C"), std::string::npos) << wrapped;
}

TEST(ErrorNaming, AConversionThroughAProxyMeasuresTheInputsHoles) {
  // Two open 1 x 1 sheets side by side (wider holes than any closing seals): refused for two components with
  // mcgim and relief named and no wrap, through the decimated proxy too (it suggested --wrap 512, which failed).
  TriMesh second = make_grid(40, 40, 1.0);
  for (Vec3& p : second.positions) p.x() += 2.0;
  const TriMesh sheets = concatenate(make_grid(40, 40, 1.0), second);
  const EmbreeDevice device;
  for (const std::string& proxy : std::vector<std::string>{"off", "1000"}) {
    ConversionRequest request;
    request.source = "sheets.ply";
    request.method.method = Method::Gim;
    request.method.size = 65;
    request.method.proxy_faces = proxy;
    const std::string refused = test::message_of<TopologyError>([&] { (void)convert_mesh(device, sheets, request); });
    EXPECT_NE(refused.find("--method mcgim (multi-chart geometry image) or --method relief converts meshes of several "
                           "components"), std::string::npos) << proxy << ": " << refused;
    EXPECT_EQ(refused.find("--wrap"), std::string::npos) << proxy << ": " << refused;
  }
}

TEST(ErrorNaming, AGenusRefusalNamesTheMethodsForItNotAWrap) {
  const TriMesh torus = make_torus(2.0, 0.5, 16, 8);
  const std::string text = refusal([] {
    throw TopologyError("the surface has genus 1 (Euler characteristic 0), not 0; spherical parametrization maps "
                        "genus-0 surfaces only: for another genus use geometry images or multi-chart geometry images");
  }, {}, &torus);
  EXPECT_NE(text.find("--method gim or --method mcgim converts another genus"), std::string::npos) << text;
  EXPECT_EQ(text.find("--wrap"), std::string::npos) << text;
}

TEST(ErrorNaming, ARefusedCoarseReliefMapNamesItsTexelsAndWhatMakesThemFiner) {
  // A unit disk with one rim vertex pulled 10^4 away: at N = 1 a texel is 156 across and the disk vanishes in
  // one; a larger --texture alone was suggested, and failed up to its largest (a probe's finding).
  TriMesh fan;
  fan.positions.push_back(Vec3::Zero());
  for (int k = 0; k < 64; ++k)
    fan.positions.emplace_back(std::cos(k * 2 * std::numbers::pi / 64), std::sin(k * 2 * std::numbers::pi / 64), 0.0);
  for (std::uint32_t k = 0; k < 64; ++k) fan.faces.push_back({0, k + 1, (k + 1) % 64 + 1});
  fan.positions[17] = Vec3(1e4, 0.0, 0.0);
  ConversionRequest request;
  request.source = "fan.ply";
  request.method.method = Method::Relief;
  request.method.grid = std::string(1, '1');  // (GCC 12 warns of an overlap in the literal assignment)
  request.fidelity.samples = 2000;
  const EmbreeDevice device;
  const std::string refused = test::message_of<InvalidInput>([&] { (void)convert_mesh(device, fan, request); });
  EXPECT_NE(refused.find("reconstructs to no triangles with area; its texels are 156 across, coarser than the "
                         "surface: a larger --texture (up to 1024) or --grid N (up to 1024) makes them finer"),
            std::string::npos)
      << refused;
  // As it says: texels of 0.6 (N = 16, T = 1024) give the disk its triangles.
  request.method.grid = "16";
  request.method.texture = 1024;
  EXPECT_GT(convert_mesh(device, fan, request).numbers.at("reconstruction_faces"), 0.0);
}

}  // namespace
}  // namespace gimforge::jobs
