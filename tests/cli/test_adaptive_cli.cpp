// End-to-end tests of adaptive geometry images (docs/adaptive.md): convert and batch with --sampling
// adaptive store the sample points and the per-round history, the reconstruction of a closed input stays
// closed, the options are refused where they do not apply, and a damaged sample_uv is named.
#include <gtest/gtest.h>

#include <cmath>

#include <hdf5.h>

#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "io/archive.h"
#include "io/batch_archive.h"
#include "io/hdf5.h"
#include "tests/cli/run_process.h"

using gimforge::test::run_gimforge;
using gimforge::test::TempDir;

namespace {

const std::string kData = GIMFORGE_TEST_DATA_DIR;

/// Rewrites dataset `path` (`count` float32 values) of the archive `file` through `edit`.
template <class Edit>
void edit_floats(const std::string& file, const char* path, std::size_t count, const Edit& edit) {
  gimforge::h5::File f = gimforge::h5::File::open(file, gimforge::h5::OpenMode::kReadWrite);
  const hid_t ds = H5Dopen2(f.id(), path, H5P_DEFAULT);
  ASSERT_GE(ds, 0);
  std::vector<float> values(count);
  ASSERT_GE(H5Dread(ds, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
  edit(values);
  ASSERT_GE(H5Dwrite(ds, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
  H5Dclose(ds);
}

/// What examples/load_archive.py prints for `expression` of item `index` of the batch archive `archive`
/// (the script written into `dir`).
gimforge::test::ProcessResult loader_prints(const TempDir& dir, const std::string& archive, int index,
                                            const std::string& expression) {
  const std::string examples = std::string(GIMFORGE_TESTS_SOURCE_DIR) + "/../examples";
  std::ofstream(dir.file("load.py")) << "import sys\nsys.path.insert(0, '" << examples
                                     << "')\nfrom load_archive import GimforgeDataset\n"
                                     << "item = GimforgeDataset(sys.argv[1])[" << index << "]\n"
                                     << "print(" << expression << ")\n";
  return gimforge::test::run_process({GIMFORGE_PYTHON, dir.file("load.py"), archive});
}

/// A conversion with --roi (its --json `j`) reported the ROI's figures and stored them in item `group` of
/// `file`: a side × side roi_mask flagging as many samples as roi_samples_after, a roi_history row per round
/// and two more (the start grid, the enhanced grid).
void expect_roi_stored(const std::string& file, const std::string& group, std::uint64_t side, const nlohmann::json& j) {
  for (const char* key : {"roi_samples_after", "roi_rms_d2_after", "roi_max_d1_after", "outside_max_d2_after",
                          "outside_rms_d2_before", "roi_weight", "roi_iterations"})
    EXPECT_TRUE(j.contains(key)) << key;
  const gimforge::io::Archive a = gimforge::io::Archive::open(file);
  const auto g = a.root().open_group(group);
  const auto mask = g.open_dataset("roi_mask");
  EXPECT_EQ(mask.shape(), (gimforge::h5::Dims{side, side}));
  std::uint64_t inside = 0;
  for (std::uint8_t v : mask.read<std::uint8_t>()) inside += v;
  EXPECT_EQ(static_cast<double>(inside), j.at("roi_samples_after").get<double>());
  const auto history = g.open_dataset("roi_history");
  EXPECT_EQ(history.shape().at(1), 9u);
  EXPECT_EQ(history.shape().at(0), static_cast<std::uint64_t>(j.at("adapt_rounds_run").get<double>()) + 2);
}

}  // namespace

TEST(CliAdaptive, ConvertStoresSamplesAndHistoryAndStaysClosed) {
  TempDir dir;
  const auto r = run_gimforge({"convert", kData + "/fist.ply", "--method", "gim", "--size", "65", "--sampling",
                               "adaptive", "--adapt-rounds", "3", "--metric-samples", "20000", "-o", dir.file("a.h5"),
                               "--json"},
                              300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  for (const char* key : {"adapt_max_before", "adapt_max_after", "adapt_rms_before", "adapt_rms_after",
                          "adapt_rounds_run", "adapt_moves", "adapt_start_strips", "seconds_adapt"})
    EXPECT_TRUE(j.contains(key)) << key << " in " << j.dump();
  EXPECT_LE(j.at("adapt_max_after").get<double>(), j.at("adapt_max_before").get<double>());
  EXPECT_LE(j.at("adapt_rounds_run").get<double>(), 3.0);
  {
    const gimforge::io::Archive a = gimforge::io::Archive::open(dir.file("a.h5"));
    const auto g = a.root().open_group("gim/fist");
    EXPECT_EQ(g.open_dataset("sample_uv").shape(), (gimforge::h5::Dims{65, 65, 2}));
    const auto history = g.open_dataset("adapt_history");
    EXPECT_EQ(history.shape().at(1), 8u);
    EXPECT_EQ(history.shape().at(0), static_cast<std::uint64_t>(j.at("adapt_rounds_run").get<double>()) + 1);
    const std::vector<float> uv = g.open_dataset("sample_uv").read<float>();
    EXPECT_EQ(uv[0], 0.0f);                       // the corners stay
    EXPECT_EQ(uv[2 * (65 * 65 - 1)], 1.0f);
  }
  const auto rec = run_gimforge({"reconstruct", dir.file("a.h5"), "-o", dir.file("a.ply")});
  ASSERT_EQ(rec.exit_code, 0) << rec.err;
  const auto info = run_gimforge({"info", dir.file("a.ply"), "--json"});
  ASSERT_EQ(info.exit_code, 0) << info.err;
  const nlohmann::json t = nlohmann::json::parse(info.out);
  EXPECT_EQ(t.at("boundary_loops"), 0);
  EXPECT_EQ(t.at("components"), 1);
  const auto preview = run_gimforge({"preview", dir.file("a.h5"), "-o", dir.file("a.png")});
  EXPECT_EQ(preview.exit_code, 0) << preview.err;
  const auto ls = run_gimforge({"ls", dir.file("a.h5")});
  ASSERT_EQ(ls.exit_code, 0) << ls.err;
  EXPECT_NE(ls.out.find("65x65x3 adaptive"), std::string::npos) << ls.out;

  // A damaged sample_uv is named: two interior samples swapped (valid values, a folded grid), then a value
  // outside the square.
  edit_floats(dir.file("a.h5"), "gim/fist/sample_uv", 65 * 65 * 2, [](std::vector<float>& uv) {
    const std::size_t a = (20 * 65 + 20) * 2, b = (20 * 65 + 21) * 2;
    std::swap(uv[a], uv[b]);
    std::swap(uv[a + 1], uv[b + 1]);
  });
  const auto folded = run_gimforge({"reconstruct", dir.file("a.h5"), "-o", dir.file("f.ply")});
  EXPECT_NE(folded.exit_code, 0);
  EXPECT_NE(folded.err.find("folded"), std::string::npos) << folded.err;
  edit_floats(dir.file("a.h5"), "gim/fist/sample_uv", 65 * 65 * 2, [](std::vector<float>& uv) {
    std::fill(uv.begin(), uv.end(), 0.5f);
    uv[100] = 2.5f;
  });
  const auto bad = run_gimforge({"reconstruct", dir.file("a.h5"), "-o", dir.file("b.ply")});
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("sample_uv"), std::string::npos) << bad.err;
}

TEST(CliAdaptive, BatchStacksTheSamplePoints) {
  TempDir dir;
  std::filesystem::create_directories(dir.file("in"));
  std::filesystem::copy_file(kData + "/fist.ply", dir.file("in/fist.ply"));
  std::filesystem::copy_file(kData + "/cathead.ply", dir.file("in/cathead.ply"));
  const auto b = run_gimforge({"batch", "--input", dir.file("in"), "--method", "gim", "--size", "65", "--sampling",
                               "adaptive", "--adapt-rounds", "2", "--metric-samples", "10000", "-o", dir.file("b.h5")},
                              300);
  ASSERT_EQ(b.exit_code, 0) << b.err;
  const auto summary = gimforge::io::read_batch_summary(dir.file("b.h5"));
  ASSERT_EQ(summary.size(), 1u);
  EXPECT_EQ(summary[0].output, "gim_65_adaptive");
  const gimforge::io::Archive a = gimforge::io::Archive::open(dir.file("b.h5"));
  const auto g = a.root().open_group("batch/gim_65_adaptive");
  EXPECT_EQ(g.open_dataset("sample_uv").shape(), (gimforge::h5::Dims{2, 2, 65, 65}));
  EXPECT_GT(g.open_group("metrics").open_dataset("adapt_moves").read<double>().at(0), 0.0);
  // The Python loader hands them out.
  const auto py = loader_prints(dir, dir.file("b.h5"), 1, "tuple(item['sample_uv'].shape)");
  ASSERT_EQ(py.exit_code, 0) << py.err;
  EXPECT_NE(py.out.find("(2, 65, 65)"), std::string::npos) << py.out;
}

TEST(CliAdaptive, FlatOctahedronSphereImageInConvertBatchAndReaders) {
  TempDir dir;
  const auto r = run_gimforge({"convert", kData + "/fist.ply", "--method", "sphere", "--domain", "flat-octa", "--n", "8",
                               "--sampling", "adaptive", "--adapt-rounds", "2", "--metric-samples", "20000", "-o",
                               dir.file("s.h5"), "--json"},
                              300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_LT(j.at("adapt_max_after").get<double>(), j.at("adapt_max_before").get<double>());
  EXPECT_GT(j.at("adapt_moves").get<double>(), 0.0);
  {
    const gimforge::io::Archive a = gimforge::io::Archive::open(dir.file("s.h5"));
    const auto g = a.root().open_group("spherical/fist");
    EXPECT_EQ(g.open_dataset("sample_uv").shape(), (gimforge::h5::Dims{17, 17, 2}));
    EXPECT_EQ(g.open_dataset("adapt_history").shape().at(1), 8u);
  }
  const auto rec = run_gimforge({"reconstruct", dir.file("s.h5"), "-o", dir.file("s.ply")});
  ASSERT_EQ(rec.exit_code, 0) << rec.err;
  const auto info = run_gimforge({"info", dir.file("s.ply"), "--json"});
  ASSERT_EQ(info.exit_code, 0) << info.err;
  const nlohmann::json t = nlohmann::json::parse(info.out);
  EXPECT_EQ(t.at("boundary_loops"), 0);
  EXPECT_EQ(t.at("components"), 1);
  const auto listing = run_gimforge({"ls", dir.file("s.h5")});
  ASSERT_EQ(listing.exit_code, 0) << listing.err;
  EXPECT_NE(listing.out.find("adaptive"), std::string::npos) << listing.out;
  EXPECT_EQ(run_gimforge({"preview", dir.file("s.h5"), "-o", dir.file("s.png")}).exit_code, 0);
  // A damaged sample_uv is named by the readers.
  edit_floats(dir.file("s.h5"), "spherical/fist/sample_uv", 17 * 17 * 2,
              [](std::vector<float>& uv) { uv[2 * (17 * 8 + 8)] = 1.5f; });
  const auto bad = run_gimforge({"reconstruct", dir.file("s.h5"), "-o", dir.file("t.ply")});
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("sample_uv"), std::string::npos) << bad.err;
  // batch: the same option, the points stacked per item.
  std::filesystem::create_directories(dir.file("in"));
  std::filesystem::copy_file(kData + "/fist.ply", dir.file("in/fist.ply"));
  const auto b = run_gimforge({"batch", "--input", dir.file("in"), "--method", "sphere", "--domain", "flat-octa", "--n",
                               "8", "--sampling", "adaptive", "--adapt-rounds", "1", "--metric-samples", "10000", "-o",
                               dir.file("b.h5")},
                              300);
  ASSERT_EQ(b.exit_code, 0) << b.err;
  {
    const gimforge::io::Archive a = gimforge::io::Archive::open(dir.file("b.h5"));
    EXPECT_EQ(a.root().open_group("batch/sphere_flat-octa_8_adaptive").open_dataset("sample_uv").shape(),
              (gimforge::h5::Dims{1, 2, 17, 17}));
  }
  // The Python loader hands them out with the image.
  const auto py = loader_prints(dir, dir.file("b.h5"), 0, "tuple(item['data'].shape), tuple(item['sample_uv'].shape)");
  ASSERT_EQ(py.exit_code, 0) << py.err;
  EXPECT_NE(py.out.find("(3, 17, 17) (2, 17, 17)"), std::string::npos) << py.out;
}

TEST(CliAdaptive, RegionOfInterestOfAFlatOctahedronImage) {
  TempDir dir;
  const auto r = run_gimforge({"convert", kData + "/fist.ply", "--method", "sphere", "--domain", "flat-octa", "--n", "16",
                               "--sampling", "adaptive", "--adapt-rounds", "2", "--roi", "auto:0.1", "--roi-gain", "3",
                               "--metric-samples", "20000", "-o", dir.file("s.h5"), "--json"},
                              300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_GE(j.at("roi_samples_enhanced").get<double>(), 2.0 * j.at("roi_samples_before").get<double>());
  EXPECT_LE(j.at("roi_max_d2_after").get<double>(), j.at("roi_max_d2_before").get<double>());
  expect_roi_stored(dir.file("s.h5"), "spherical/fist", 33, j);
  const auto listing = run_gimforge({"ls", dir.file("s.h5")});
  EXPECT_NE(listing.out.find("adaptive roi"), std::string::npos) << listing.out;
  const auto preview = run_gimforge({"preview", dir.file("s.h5"), "-o", dir.file("pv")});
  ASSERT_EQ(preview.exit_code, 0) << preview.err;
  EXPECT_TRUE(std::filesystem::exists(dir.file("pv/fist_roi.png")));
  // The ROI picture never replaces the archive it is drawn from.
  std::filesystem::copy_file(dir.file("s.h5"), dir.file("pv/fist_roi.png"), std::filesystem::copy_options::overwrite_existing);
  const auto over = run_gimforge({"preview", dir.file("pv/fist_roi.png"), "-o", dir.file("pv")});
  EXPECT_NE(over.exit_code, 0);
  std::string magic(8, '\0');
  std::ifstream(dir.file("pv/fist_roi.png"), std::ios::binary).read(magic.data(), 8);
  EXPECT_EQ(magic, std::string("\x89HDF\r\n\x1a\n", 8));  // still the archive
  const auto rec = run_gimforge({"reconstruct", dir.file("s.h5"), "-o", dir.file("s.ply")});
  ASSERT_EQ(rec.exit_code, 0) << rec.err;
  const auto info = run_gimforge({"info", dir.file("s.ply"), "--json"});
  EXPECT_EQ(nlohmann::json::parse(info.out).at("boundary_loops"), 0);
  // compress reports the ROI's samples as for a geometry image (it reported null).
  for (const char* codec : {"j2k", "quant12"}) {
    std::vector<std::string> args{"compress", dir.file("s.h5"), "--codec", codec, "--no-metric", "--json", "-o",
                                  dir.file(std::string("c_") + codec + ".h5")};
    if (std::string(codec) == "j2k") args.insert(args.end(), {"--bytes", "6000"});
    const auto c = run_gimforge(args);
    ASSERT_EQ(c.exit_code, 0) << c.err;
    const nlohmann::json item = nlohmann::json::parse(c.out).at("items").at(0);
    ASSERT_TRUE(item.at("roi_image_psnr").is_number()) << item.dump();
    EXPECT_GT(item.at("roi_image_psnr").get<double>(), 50.0) << item.dump();
  }
  // A ROI the image cannot feed (half of fist in a 33² image: enhancement stretches the triangles along the
  // fixed seams, and the ROI ends worse than it started) keeps the start grid and says so.
  const auto worse = run_gimforge({"convert", kData + "/fist.ply", "--method", "sphere", "--domain", "flat-octa", "--n",
                                   "16", "--sampling", "adaptive", "--roi", "box:0,-9,-9,9,9,9", "--no-metric", "--json",
                                   "-o", dir.file("w.h5")},
                                  300);
  ASSERT_EQ(worse.exit_code, 0) << worse.err;
  EXPECT_NE(worse.err.find("the start grid was kept"), std::string::npos) << worse.err;
  const nlohmann::json kept = nlohmann::json::parse(worse.out);
  EXPECT_EQ(kept.at("roi_kept_start").get<double>(), 1.0);
  EXPECT_EQ(kept.at("roi_max_d2_after").get<double>(), kept.at("roi_max_d2_before").get<double>());
  edit_floats(dir.file("w.h5"), "spherical/fist/sample_uv", 33 * 33 * 2, [](std::vector<float>& uv) {
    for (std::size_t k = 0; k < 33 * 33; ++k) {
      EXPECT_NEAR(uv[2 * k], static_cast<double>(k % 33) / 32.0, 1e-6);
      EXPECT_NEAR(uv[2 * k + 1], static_cast<double>(k / 33) / 32.0, 1e-6);
    }
  });
  // The vertex forms through the cut along the seams, in batch: the ROI's figures among the metrics.
  std::filesystem::create_directories(dir.file("in"));
  std::filesystem::copy_file(kData + "/fist.ply", dir.file("in/fist.ply"));
  std::ofstream(dir.file("ids.txt")) << "0 1 2 3 4 5 6 7 8 9 10\n";
  const auto b = run_gimforge({"batch", "--input", dir.file("in"), "--method", "sphere", "--domain", "flat-octa", "--n",
                               "8", "--sampling", "adaptive", "--adapt-rounds", "1", "--roi",
                               "vertices:" + dir.file("ids.txt"), "--metric-samples", "10000", "-o", dir.file("b.h5")},
                              300);
  ASSERT_EQ(b.exit_code, 0) << b.err;
  const gimforge::io::Archive a = gimforge::io::Archive::open(dir.file("b.h5"));
  const auto metrics = a.root().open_group("batch/sphere_flat-octa_8_adaptive_roi/metrics");
  EXPECT_GT(metrics.open_dataset("roi_samples_enhanced").read<double>().at(0),
            metrics.open_dataset("roi_samples_before").read<double>().at(0));
}

TEST(CliAdaptive, OptionsAreRefusedWhereTheyDoNotApply) {
  TempDir dir;
  const std::string mesh = kData + "/fist.ply";
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases{
      {{"--adapt-rounds", "4"}, "--sampling adaptive"},
      {{"--adapt-start", "strips"}, "--sampling adaptive"},
      {{"--sampling", "sometimes"}, "--sampling"},
      {{"--sampling", "adaptive", "--adapt-start", "middle"}, "--adapt-start"},
      {{"--sampling", "adaptive", "--adapt-rounds", "5000"}, "--adapt-rounds"},
      {{"--method", "sphere", "--sampling", "adaptive"}, "--domain flat-octa"},
      {{"--method", "mcgim", "--sampling", "adaptive"}, "--method gim and sphere"},
      {{"--method", "sphere", "--domain", "octa", "--sampling", "adaptive", "--roi", "auto"}, "--domain flat-octa"},
      {{"--method", "mcgim", "--roi", "auto"}, "--method gim and sphere"},
      {{"--sampling", "adaptive", "--optimize"}, "choose one"}};
  for (const auto& [extra, says] : cases) {
    std::vector<std::string> args{"convert", mesh, "-o", dir.file("x.h5")};
    args.insert(args.end(), extra.begin(), extra.end());
    const auto r = run_gimforge(args);
    EXPECT_EQ(r.exit_code, 2) << extra.front() << ": " << r.err;
    EXPECT_NE(r.err.find(says), std::string::npos) << r.err;
  }
  EXPECT_FALSE(std::filesystem::exists(dir.file("x.h5")));
  // Job files likewise.
  std::ofstream(dir.file("job.toml")) << "[[collection]]\ninput = \"" << kData
                                      << "\"\n[[output]]\nmethod = \"gim\"\nsize = 65\nadapt_rounds = 3\n";
  const auto job = run_gimforge({"batch", "--job", dir.file("job.toml"), "-o", dir.file("j.h5")});
  EXPECT_NE(job.exit_code, 0);
  EXPECT_NE(job.err.find("adaptive"), std::string::npos) << job.err;
}

TEST(CliAdaptive, RegionOfInterestInConvertBatchAndPreview) {
  TempDir dir;
  // convert --roi auto: the ROI's samples and its directed distance, the mask and its history.
  const auto r = run_gimforge({"convert", kData + "/fist.ply", "--method", "gim", "--size", "65", "--sampling",
                               "adaptive", "--adapt-rounds", "3", "--roi", "auto:0.1", "--roi-gain", "3",
                               "--metric-samples", "20000", "-o", dir.file("r.h5"), "--json"},
                              300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err.find("outside the region of interest the error grew"), std::string::npos) << r.err;  // 4×
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_GE(j.at("roi_samples_enhanced").get<double>(), 3.0 * j.at("roi_samples_before").get<double>());
  EXPECT_LT(j.at("roi_max_d2_after").get<double>(), j.at("roi_max_d2_before").get<double>());
  expect_roi_stored(dir.file("r.h5"), "gim/fist", 65, j);
  // compress --codec j2k-roi: the ROI first at equal bytes (a higher PSNR over the ROI's samples than plain
  // JPEG 2000), decoded transparently and closed after fusing; refused without a ROI or a byte budget.
  {
    const auto roi_first = run_gimforge({"compress", dir.file("r.h5"), "--codec", "j2k-roi", "--bytes", "2500",
                                         "--metric-samples", "5000", "--json", "-o", dir.file("cr.h5")});
    ASSERT_EQ(roi_first.exit_code, 0) << roi_first.err;
    const auto plain = run_gimforge({"compress", dir.file("r.h5"), "--codec", "j2k", "--bytes", "2500",
                                     "--metric-samples", "5000", "--json", "-o", dir.file("cp.h5")});
    ASSERT_EQ(plain.exit_code, 0) << plain.err;
    const nlohmann::json a = nlohmann::json::parse(roi_first.out).at("items").at(0);
    const nlohmann::json b = nlohmann::json::parse(plain.out).at("items").at(0);
    EXPECT_EQ(a.at("codec"), "j2k-roi");
    EXPECT_LE(a.at("bytes").get<std::uint64_t>(), 2500u);
    EXPECT_GT(a.at("roi_image_psnr").get<double>(), b.at("roi_image_psnr").get<double>() + 2.0);
    // What a reader gets (decompress: decoded and fused) is what compress measured.
    const auto dec_roi = run_gimforge({"decompress", dir.file("cr.h5"), "-o", dir.file("crd.h5")});
    ASSERT_EQ(dec_roi.exit_code, 0) << dec_roi.err;
    {
      const auto stored = gimforge::io::Archive::open(dir.file("r.h5")).root().open_dataset("gim/fist/geometry").read<float>();
      const auto decoded = gimforge::io::Archive::open(dir.file("crd.h5")).root().open_dataset("gim/fist/geometry").read<float>();
      ASSERT_EQ(stored.size(), decoded.size());
      double lo[3] = {1e30, 1e30, 1e30}, hi[3] = {-1e30, -1e30, -1e30}, sum = 0.0;
      for (std::size_t k = 0; k < stored.size(); ++k) {
        lo[k % 3] = std::min(lo[k % 3], double{stored[k]});
        hi[k % 3] = std::max(hi[k % 3], double{stored[k]});
        sum += std::pow(double{decoded[k]} - double{stored[k]}, 2);
      }
      const double diagonal = std::sqrt(std::pow(hi[0] - lo[0], 2) + std::pow(hi[1] - lo[1], 2) + std::pow(hi[2] - lo[2], 2));
      const double psnr = 20.0 * std::log10(diagonal / std::sqrt(sum / static_cast<double>(stored.size() / 3)));
      EXPECT_NEAR(psnr, a.at("image_psnr").get<double>(), 0.01);
    }
    const auto rec_roi = run_gimforge({"reconstruct", dir.file("cr.h5"), "-o", dir.file("cr.ply")});
    ASSERT_EQ(rec_roi.exit_code, 0) << rec_roi.err;
    const auto info_roi = run_gimforge({"info", dir.file("cr.ply"), "--json"});
    EXPECT_EQ(nlohmann::json::parse(info_roi.out).at("boundary_loops"), 0);
    for (const auto& [args, says] : std::vector<std::pair<std::vector<std::string>, std::string>>{
             {{"compress", dir.file("cp.h5"), "--codec", "j2k-roi", "--bytes", "2500", "-o", dir.file("x.h5")}, "already coded"},
             {{"compress", dir.file("r.h5"), "--codec", "j2k-roi", "--psnr", "40", "-o", dir.file("x.h5")}, "--bytes"},
             {{"batch", "--input", kData, "--method", "gim", "--size", "65", "--codec", "j2k-roi", "--rate", "3000", "-o",
               dir.file("x.h5")},
              "--roi SPEC"}}) {
      const auto refused = run_gimforge(args, 120);
      EXPECT_NE(refused.exit_code, 0) << says;
      EXPECT_NE(refused.err.find(says), std::string::npos) << refused.err;
    }
  }
  const auto preview = run_gimforge({"preview", dir.file("r.h5"), "-o", dir.file("pv")});
  ASSERT_EQ(preview.exit_code, 0) << preview.err;
  EXPECT_TRUE(std::filesystem::exists(dir.file("pv/fist_roi.png")));
  // It reads back (every quad of sample_uv convex in float32) and stays closed.
  const auto rec = run_gimforge({"reconstruct", dir.file("r.h5"), "-o", dir.file("r.ply")});
  ASSERT_EQ(rec.exit_code, 0) << rec.err;
  const auto info = run_gimforge({"info", dir.file("r.ply"), "--json"});
  ASSERT_EQ(info.exit_code, 0) << info.err;
  EXPECT_EQ(nlohmann::json::parse(info.out).at("boundary_loops"), 0);

  // The picture preview drew (white pixels: samples in the ROI, in pixel space) read back as --roi mask:
  // the form is accepted and selects part of the square.
  const auto masked = run_gimforge({"convert", kData + "/fist.ply", "--method", "gim", "--size", "65", "--sampling",
                                    "adaptive", "--adapt-rounds", "1", "--roi", "mask:" + dir.file("pv/fist_roi.png"),
                                    "--no-metric", "-o", dir.file("m.h5"), "--json"},
                                   300);
  ASSERT_EQ(masked.exit_code, 0) << masked.err;
  EXPECT_GT(nlohmann::json::parse(masked.out).at("roi_samples_before").get<double>(), 0.0);

  // batch: a job file's roi, the ROI's figures among the metrics.
  std::filesystem::create_directories(dir.file("in"));
  std::filesystem::copy_file(kData + "/fist.ply", dir.file("in/fist.ply"));
  std::ofstream(dir.file("job.toml")) << "[[collection]]\ninput = \"" << dir.file("in")
                                      << "\"\n[[output]]\nmethod = \"gim\"\nsize = 65\nsampling = \"adaptive\"\n"
                                         "adapt_rounds = 2\nroi = \"auto:0.2\"\nroi_gain = 2\n"
                                         "[[output]]\nmethod = \"gim\"\nsize = 65\nsampling = \"adaptive\"\n"
                                         "adapt_rounds = 2\nroi = \"auto:0.2\"\nroi_gain = 2\ncodec = \"j2k-roi\"\n"
                                         "rate = 3000\nname = \"coded\"\n";
  const auto b = run_gimforge({"batch", "--job", dir.file("job.toml"), "--metric-samples", "10000", "-o", dir.file("b.h5")}, 300);
  ASSERT_EQ(b.exit_code, 0) << b.err;
  const gimforge::io::Archive a = gimforge::io::Archive::open(dir.file("b.h5"));
  const auto metrics = a.root().open_group("batch/gim_65_adaptive_roi/metrics");
  EXPECT_GE(metrics.open_dataset("roi_samples_enhanced").read<double>().at(0),
            2.0 * metrics.open_dataset("roi_samples_before").read<double>().at(0));
  // The same item coded ROI first (batch --codec j2k-roi) decodes through decompress.
  EXPECT_TRUE(a.root().exists("batch/coded/items/0/geometry_code"));
  const auto dec = run_gimforge({"decompress", dir.file("b.h5"), "-o", dir.file("bd.h5")});
  ASSERT_EQ(dec.exit_code, 0) << dec.err;
  const auto rec_batch = run_gimforge({"reconstruct", dir.file("bd.h5"), "--name", "gim/coded.0", "-o", dir.file("b0.ply")});
  ASSERT_EQ(rec_batch.exit_code, 0) << rec_batch.err;
  const auto info_batch = run_gimforge({"info", dir.file("b0.ply"), "--json"});
  ASSERT_EQ(info_batch.exit_code, 0) << info_batch.err;
  EXPECT_EQ(nlohmann::json::parse(info_batch.out).at("boundary_loops"), 0);
}

TEST(CliAdaptive, ASteepPriceOutsideTheRegionOfInterestIsSaid) {
  // A corner of fist's bounding box already holds 670 of a 65² image's samples; at the default gain it ends with
  // about 2,870, and the error outside grows 30× (the whole surface's PSNR 61 → 32 dB): once without a word.
  TempDir dir;
  const auto r = run_gimforge({"convert", kData + "/fist.ply", "--method", "gim", "--size", "65", "--sampling",
                               "adaptive", "--adapt-rounds", "0", "--roi", "box:0,0,0,0.5,0.5,0.5", "--metric-samples",
                               "20000", "-o", dir.file("r.h5")},
                              300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("fist.ply: --roi: outside the region of interest the error grew"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("a lower --roi-gain or a larger image costs the rest less"), std::string::npos) << r.err;
}

TEST(CliAdaptive, BadRegionsOfInterestGiveOneClearLine) {
  TempDir dir;
  const std::string mesh = kData + "/fist.ply";
  std::ofstream(dir.file("words.txt")) << "12 x\n";
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases{
      {{"--roi", "auto"}, "--sampling adaptive"},
      {{"--sampling", "adaptive", "--roi", "box:1,2"}, "6 numbers"},
      {{"--sampling", "adaptive", "--roi", "blob:1"}, "unknown kind 'blob'"},
      {{"--sampling", "adaptive", "--roi", "auto", "--roi-gain", "0.5"}, "--roi-gain"},
      {{"--sampling", "adaptive", "--roi", "vertices:" + dir.file("none.txt")}, "none.txt: no such file"},
      {{"--sampling", "adaptive", "--roi", "vertices:" + dir.file("words.txt")}, "words.txt:1: 'x' is not a vertex index"},
      {{"--sampling", "adaptive", "--roi", "mask:" + dir.file("words.txt")}, "words.txt: not a readable PNG"},
      {{"--sampling", "adaptive", "--roi", "box:1e9,1e9,1e9,2e9,2e9,2e9"}, "selects no vertex"},
      {{"--sampling", "adaptive", "--roi", "color:ff0000"}, "no vertex colours"},
      {{"--sampling", "adaptive", "--roi", "scalar:quality"}, "no scalar property 'quality'"},
      {{"--sampling", "adaptive", "--roi", "auto", "--size", "1025"}, "images up to 513×513"},
      {{"--method", "sphere", "--roi", "auto"}, "--sampling adaptive"},
      {{"--method", "sphere", "--domain", "flat-octa", "--n", "300", "--sampling", "adaptive", "--roi", "auto"},
       "images up to 513×513"},
      {{"--method", "relief", "--roi", "auto"}, "--method gim and sphere"},
      {{"--sampling", "adaptive", "--roi-gain", "2"}, "--roi only"}};
  for (const auto& [extra, says] : cases) {
    std::vector<std::string> args{"convert", mesh, "--size", "65", "-o", dir.file("x.h5")};
    args.insert(args.end(), extra.begin(), extra.end());
    // --size is gim's, and some cases give their own.
    if (extra.front() == "--method" || std::find(extra.begin(), extra.end(), "--size") != extra.end())
      args.erase(args.begin() + 2, args.begin() + 4);
    const auto r = run_gimforge(args, 120);
    EXPECT_NE(r.exit_code, 0) << extra.back();
    EXPECT_NE(r.err.find(says), std::string::npos) << extra.back() << ": " << r.err;
    // One line (a usage error adds the hint "Run with --help ...").
    std::string err = r.err;
    if (const auto hint = err.find("Run with --help"); hint != std::string::npos) err.resize(hint);
    EXPECT_LE(std::count(err.begin(), err.end(), '\n'), 1) << r.err;
  }
  EXPECT_FALSE(std::filesystem::exists(dir.file("x.h5")));
}

TEST(CliAdaptive, BatchRefusesAMissingRoiFileUpFrontAndReadsJobFilePathsFromTheJobsFolder) {
  TempDir dir;
  std::filesystem::create_directories(dir.file("job/in"));
  std::filesystem::copy_file(kData + "/fist.ply", dir.file("job/in/fist.ply"));
  // A missing mask or vertex list: one line before any item runs (it used to fail every item, twice), no archive.
  for (const std::string& roi : {"mask:" + dir.file("none.png"), "vertices:" + dir.file("none.txt")}) {
    const auto r = run_gimforge({"batch", "--input", dir.file("job/in"), "--size", "65", "--sampling", "adaptive", "--roi",
                                 roi, "-o", dir.file("b.h5")});
    EXPECT_NE(r.exit_code, 0) << roi;
    EXPECT_NE(r.err.find("no such file"), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("attempt"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir.file("b.h5"))) << roi;
  }
  // In a job file a relative vertex list is found beside the job file, like its collections, from any folder.
  std::ofstream(dir.file("job/verts.txt")) << "0 1 2 3 4 5 6 7 8 9\n";
  std::ofstream(dir.file("job/job.toml")) << "[[collection]]\ninput = \"in\"\n[[output]]\nmethod = \"gim\"\nsize = 65\n"
                                              "sampling = \"adaptive\"\nadapt_rounds = 0\nroi = \"vertices:verts.txt\"\n";
  const auto r = run_gimforge({"batch", "--job", dir.file("job/job.toml"), "--no-metric", "-o", dir.file("j.h5")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const gimforge::io::Archive a = gimforge::io::Archive::open(dir.file("j.h5"));
  const auto metrics = a.root().open_group("batch/gim_65_adaptive_roi/metrics");
  EXPECT_GT(metrics.open_dataset("roi_samples_before").read<double>().at(0), 0.0);
}
