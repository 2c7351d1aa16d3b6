// End-to-end tests of compression (docs/compression.md, issue #19): `compress` writes items within their byte
// budget, everything counted; reconstruct and preview read them transparently; decoded geometry images are
// watertight after fusing and spherical ones without it; PSNR targets hold; damaged payloads and impossible
// requests are one clear error line.
#include <gtest/gtest.h>

#include <hdf5.h>
#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "io/archive.h"
#include "io/coded_image.h"
#include "io/gim_archive.h"
#include "io/hdf5.h"
#include "io/mcgim_archive.h"
#include "kernels/mcgim/mcgim_fuse.h"
#include "io/sphere_archive.h"
#include "tests/cli/run_process.h"

using gimforge::test::run_gimforge;
using gimforge::test::run_process;
using gimforge::test::TempDir;

namespace {

const std::string kData = GIMFORGE_TEST_DATA_DIR;

/// fist.ply as a 65 x 65 geometry image and a flat-octahedron spherical image at n = 32, in one archive.
std::string converted(TempDir& dir) {
  const std::string a = dir.file("a.h5");
  const auto g = run_gimforge({"-q", "convert", kData + "/fist.ply", "--method", "gim", "--size", "65", "--metric-samples",
                               "20000", "-o", a},
                              300);
  EXPECT_EQ(g.exit_code, 0) << g.err;
  const auto s = run_gimforge({"-q", "convert", kData + "/fist.ply", "--method", "sphere", "--domain", "flat-octa", "--n",
                               "32", "--metric-samples", "20000", "-o", a},
                              300);
  EXPECT_EQ(s.exit_code, 0) << s.err;
  return a;
}

nlohmann::json mesh_info(const std::string& ply) {
  const auto r = run_gimforge({"info", ply, "--json"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return nlohmann::json::parse(r.out);
}

}  // namespace

TEST(CliCompress, DecompressCopiesFloatItemsWholeAndCompressRefusesWhatItCannotStore) {
  TempDir dir;
  const std::string a = converted(dir);
  // Nothing to decode: the items come over whole (sphere parametrization, provenance), not rewritten.
  const std::string d = dir.file("d.h5");
  const auto copied = run_gimforge({"decompress", a, "-o", d});
  ASSERT_EQ(copied.exit_code, 0) << copied.err;
  // ... and said (a probe's never-compressed archive was copied without a word).
  EXPECT_NE(copied.err.find("2 of its 2 images are neither coded nor quantized (not written by compress): copied as stored"),
            std::string::npos) << copied.err;
  {
    const gimforge::io::Archive out = gimforge::io::Archive::open(d);
    EXPECT_TRUE(out.root().exists("spherical/fist/parametrization/sphere"));
    EXPECT_TRUE(out.root().open_group("gim/fist").has_attribute("command_line"));
  }
  // Float32 values near ±3.4e38 (which could not be stored as offset + scale · q either) lie where no mesh gimforge
  // reads does: the reader refuses them, one line naming the archive, the item and the sample, no output.
  const std::string huge = dir.file("huge.h5");
  std::filesystem::copy_file(a, huge);
  {
    gimforge::io::Archive archive = gimforge::io::Archive::open(huge, gimforge::h5::OpenMode::kReadWrite);
    gimforge::h5::Dataset g = archive.root().open_dataset("gim/fist/geometry");
    std::vector<float> xyz = g.read<float>();
    xyz[0] = 3e38f;
    xyz[3] = -3e38f;
    g.write(xyz);
    archive.close();
  }
  for (const char* codec : {"quant12", "j2k"}) {
    std::vector<std::string> args{"compress", huge, "--name", "gim/fist", "--codec", codec, "--no-metric", "-o", dir.file("q.h5")};
    if (std::string(codec) == "j2k") args.insert(args.end(), {"--bytes", "8000"});
    const auto r = run_gimforge(args);
    EXPECT_EQ(r.exit_code, 1) << codec;
    EXPECT_NE(r.err.find("huge.h5: geometry image 'fist': dataset 'geometry': sample 0 has a coordinate of magnitude 3e+38"),
              std::string::npos)
        << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir.file("q.h5")));
  }
}

TEST(CliCompress, CodedItemsFitTheirBytesAndReconstructWatertight) {
  TempDir dir;
  const std::string a = converted(dir);
  const auto r = run_gimforge({"compress", a, "--bytes", "5000", "--metric-samples", "20000", "--json", "-o", dir.file("c.h5")}, 300);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j.at("items").size(), 2u);
  for (const auto& item : j.at("items")) {
    EXPECT_LE(item.at("bytes").get<std::uint64_t>(), 5000u) << item.dump();
    EXPECT_GT(item.at("bytes").get<std::uint64_t>(), 4000u) << item.dump();  // the budget is spent
    EXPECT_EQ(item.at("trials").size(), 2u);                                  // auto tried j2k and wavelet
    EXPECT_GT(item.at("surface_psnr").get<double>(), 50.0) << item.dump();
  }
  EXPECT_EQ(j.at("items")[1].at("item"), "spherical/fist");
  // Watertight as stored values: glued pixels of the geometry image (after fusing) and duplicated samples of
  // the spherical image (the extension rules, no fusing) are bit-identical once decoded.
  ASSERT_EQ(run_gimforge({"compress", a, "--codec", "wavelet", "--bytes", "5000", "--no-metric", "--json", "-o",
                          dir.file("w.h5")})
                .exit_code,
            0);
  ASSERT_EQ(run_gimforge({"decompress", dir.file("w.h5"), "-o", dir.file("d.h5")}).exit_code, 0);
  {
    const gimforge::io::Archive d = gimforge::io::Archive::open(dir.file("d.h5"));
    const gimforge::GeometryImage gim = gimforge::io::read_geometry_image(d, "fist");
    const std::vector<std::uint32_t> rep = gimforge::boundary_classes(gim.sideband, gim.size);
    std::size_t glued = 0;
    for (std::size_t p = 0; p < rep.size(); ++p)
      if (rep[p] != p) {
        ++glued;
        for (std::size_t c = 0; c < 3; ++c) ASSERT_EQ(gim.positions[3 * p + c], gim.positions[3 * rep[p] + c]) << p;
      }
    EXPECT_GT(glued, 50u);
    const gimforge::SphericalImage sph = gimforge::io::read_spherical_image(d, "fist");
    const std::vector<std::uint32_t> ids = sph.layout().vertex_ids();
    std::vector<std::int64_t> first(sph.layout().num_domain_points(), -1);
    std::size_t duplicates = 0;
    for (std::size_t k = 0; k < ids.size(); ++k) {
      if (first[ids[k]] < 0) {
        first[ids[k]] = static_cast<std::int64_t>(k);
        continue;
      }
      ++duplicates;
      const auto f = static_cast<std::size_t>(first[ids[k]]);
      for (std::size_t c = 0; c < 3; ++c) ASSERT_EQ(sph.positions[3 * k + c], sph.positions[3 * f + c]) << k;
    }
    EXPECT_GT(duplicates, 100u);
  }
  for (const char* kind : {"gim/fist", "spherical/fist"}) {
    const std::string ply = dir.file(std::string(kind).substr(0, 3) + ".ply");
    const auto rec = run_gimforge({"reconstruct", dir.file("c.h5"), "--name", kind, "-o", ply});
    ASSERT_EQ(rec.exit_code, 0) << rec.err;
    const nlohmann::json t = mesh_info(ply);
    EXPECT_EQ(t.at("boundary_loops"), 0) << kind;  // fused (gim) or watertight by construction (spherical)
    EXPECT_EQ(t.at("components"), 1) << kind;
  }
  const auto preview = run_gimforge({"preview", dir.file("c.h5"), "--name", "gim/fist", "-o", dir.file("png")});
  EXPECT_EQ(preview.exit_code, 0) << preview.err;
  // ls names the bytes compress counted (and --bytes bounds) beside the payload's; it showed the payload alone.
  const auto ls = run_gimforge({"ls", dir.file("c.h5")});
  for (const auto& item : j.at("items"))
    EXPECT_NE(ls.out.find(fmt::format("{} B stored (payload ", item.at("bytes").get<std::uint64_t>())), std::string::npos)
        << ls.out;
}

TEST(CliCompress, EachCodecAndTargetHolds) {
  TempDir dir;
  const std::string a = converted(dir);
  // A PSNR target: the decoded samples (fused) are at least that close to the stored ones.
  for (const char* codec : {"j2k", "wavelet"}) {
    const std::string out = dir.file(std::string(codec) + ".h5");
    const auto r = run_gimforge({"compress", a, "--name", "gim/fist", "--codec", codec, "--psnr", "70", "--no-metric",
                                 "--json", "-o", out});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json item = nlohmann::json::parse(r.out).at("items")[0];
    EXPECT_GE(item.at("image_psnr").get<double>(), 70.0) << codec;
    EXPECT_EQ(item.at("codec"), codec);
  }
  // A target one codec cannot meet: auto keeps the other (lossless JPEG 2000 of 16-bit planes stops near
  // 100 dB, the wavelet coder goes on).
  const auto high = run_gimforge({"compress", a, "--name", "gim/fist", "--psnr", "115", "--no-metric", "--json", "-o",
                                  dir.file("h.h5")});
  ASSERT_EQ(high.exit_code, 0) << high.err;
  const nlohmann::json h = nlohmann::json::parse(high.out).at("items")[0];
  EXPECT_EQ(h.at("codec"), "wavelet");
  EXPECT_GE(h.at("image_psnr").get<double>(), 115.0);
  // Lossless JPEG 2000 of the 16-bit planes and 12-bit quantization.
  const auto lossless = run_gimforge({"compress", a, "--codec", "j2k", "--lossless", "--no-metric", "--json", "-o", dir.file("l.h5")});
  ASSERT_EQ(lossless.exit_code, 0) << lossless.err;
  // (The parsed document is kept in a variable: a range-for over a temporary's member reads freed memory.)
  const nlohmann::json lossless_json = nlohmann::json::parse(lossless.out);
  for (const auto& item : lossless_json.at("items")) EXPECT_GT(item.at("image_psnr").get<double>(), 95.0);
  const auto q12 = run_gimforge({"compress", a, "--codec", "quant12", "--json", "--metric-samples", "20000", "-o", dir.file("q.h5")});
  ASSERT_EQ(q12.exit_code, 0) << q12.err;
  const nlohmann::json q12_json = nlohmann::json::parse(q12.out);
  {
    // The bytes reported are those the item stores, counted again once the file is closed (the spherical
    // item's open geometry dataset kept its chunks in HDF5's cache: 795 bytes reported for 57 KB stored).
    const auto q = gimforge::io::Archive::open(dir.file("q.h5"));
    for (const auto& item : q12_json.at("items")) {
      EXPECT_GT(item.at("image_psnr").get<double>(), 75.0);
      EXPECT_LT(item.at("bytes").get<std::uint64_t>(), item.at("bytes_before").get<std::uint64_t>() / 2);
      const auto group = q.root().open_group(item.at("item").get<std::string>());
      EXPECT_EQ(item.at("bytes").get<std::uint64_t>(), gimforge::io::stored_bytes(group)) << item.dump();
      EXPECT_GT(item.at("bytes").get<std::uint64_t>(), gimforge::io::dataset_stored_bytes(group, "geometry")) << item.dump();
    }
  }
  const auto rec = run_gimforge({"reconstruct", dir.file("q.h5"), "--name", "spherical/fist", "-o", dir.file("q.ply")});
  ASSERT_EQ(rec.exit_code, 0) << rec.err;
  EXPECT_EQ(mesh_info(dir.file("q.ply")).at("boundary_loops"), 0);
  // The Python loader reads the positions gimforge reads (decompress writes them: rounded to float32 once, where
  // the loader kept offset + scale·q in float64), and refuses what gimforge's readers refuse (it returned NaN or
  // far-off positions).
  ASSERT_EQ(run_gimforge({"decompress", dir.file("q.h5"), "-o", dir.file("decoded.h5")}).exit_code, 0);
  const std::string examples = std::string(GIMFORGE_TESTS_SOURCE_DIR) + "/../examples";
  const auto py = run_process(
      {GIMFORGE_PYTHON, "-c",
       "import sys, shutil, h5py, numpy as np; sys.path.insert(0, sys.argv[1]); from load_archive import read_image\n"
       "src, tmp = sys.argv[2], sys.argv[3]\n"
       "assert np.isfinite(read_image(src, 'gim/fist')['positions']).all()\n"
       "for item in ('gim/fist', 'spherical/fist'):\n"
       "    ours = read_image(src, item, frame='local')['positions']\n"
       "    theirs = read_image(sys.argv[4], item, frame='local')['positions']\n"
       "    assert np.array_equal(ours, theirs, equal_nan=True), (item, np.nanmax(np.abs(ours - theirs)))\n"
       "def damaged(edit, needle):\n"
       "    shutil.copy(src, tmp)\n"
       "    with h5py.File(tmp, 'r+') as f: edit(f['gim/fist/geometry'])\n"
       "    try:\n"
       "        read_image(tmp, 'gim/fist')\n"
       "    except ValueError as e:\n"
       "        assert needle in str(e), e\n"
       "        return\n"
       "    raise SystemExit('accepted: ' + needle)\n"
       "def put(name, value):\n"
       "    return lambda ds: ds.attrs.__setitem__(name, value)\n"
       "damaged(put('scale', np.array([np.nan, 1e-4, 1e-4])), 'leave the range of float32')\n"
       "damaged(put('scale', np.array([0.0, 1e-4, 1e-4])), 'leave the range of float32')\n"
       "damaged(put('offset', np.array([1e39, 0.0, 0.0])), 'leave the range of float32')\n"
       "damaged(put('scale', np.array([1, 2, 3])), 'not 1 or 3 float64')\n"
       "damaged(put('bits', 11), 'bits = 11')\n"
       "damaged(put('bits', '12'), 'bits = ')\n"
       "def high(ds):\n"
       "    q = ds[()]; q[0, 0, 0] = 65535; ds[...] = q\n"
       "damaged(high, 'above 2^bits - 1 = 4095')\n",
       examples, dir.file("q.h5"), dir.file("qd.h5"), dir.file("decoded.h5")});
  EXPECT_EQ(py.exit_code, 0) << py.err << py.out;
}

TEST(CliCompress, DamagedPayloadsAndImpossibleRequestsAreOneLine) {
  TempDir dir;
  const std::string a = converted(dir);
  const std::string c = dir.file("c.h5");
  ASSERT_EQ(run_gimforge({"compress", a, "--bytes", "4000", "--no-metric", "-o", c}).exit_code, 0);
  {  // flip one byte of each payload
    gimforge::io::Archive archive = gimforge::io::Archive::open(c, gimforge::h5::OpenMode::kReadWrite);
    for (const char* path : {"gim/fist/geometry_code", "spherical/fist/geometry_code"}) {
      gimforge::h5::Dataset ds = archive.root().open_dataset(path);
      std::vector<std::uint8_t> bytes = ds.read<std::uint8_t>();
      bytes[bytes.size() / 2] ^= 0x10;
      ds.write(bytes);
    }
    archive.close();
  }
  for (const char* kind : {"gim/fist", "spherical/fist"}) {
    const auto r = run_gimforge({"reconstruct", c, "--name", kind, "-o", dir.file("x.ply")});
    EXPECT_EQ(r.exit_code, 1) << kind;
    EXPECT_NE(r.err.find("checksum mismatch"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  {  // a spherical payload relabelled as ROI-first coding (which only geometry images use)
    const std::string c2 = dir.file("c2.h5");
    ASSERT_EQ(run_gimforge({"compress", a, "--name", "spherical/fist", "--bytes", "4000", "--no-metric", "-o", c2}).exit_code, 0);
    {
      gimforge::io::Archive archive = gimforge::io::Archive::open(c2, gimforge::h5::OpenMode::kReadWrite);
      gimforge::h5::Dataset ds = archive.root().open_dataset("spherical/fist/geometry_code");
      ds.set_attribute("codec", std::string("j2k-roi"));
      archive.close();
    }
    const auto r = run_gimforge({"reconstruct", c2, "-o", dir.file("x.ply")});
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.err.find("only geometry images (gim) use"), std::string::npos) << r.err;
  }
  // Refused option values are usage errors (exit 2), as docs/cli.md says of every command.
  const auto small = run_gimforge({"compress", a, "--bytes", "500", "-o", dir.file("s.h5")});
  EXPECT_EQ(small.exit_code, 2);
  EXPECT_NE(small.err.find("not in range 1024"), std::string::npos) << small.err;
  for (const std::vector<std::string>& target : {std::vector<std::string>{"--psnr", "1000"},
                                                 std::vector<std::string>{"--psnr", "nan"},
                                                 std::vector<std::string>{"--bytes", "5000", "--psnr", "50"},
                                                 // as convert and batch refuse it (compress ignored the samples)
                                                 std::vector<std::string>{"--bytes", "5000", "--no-metric",
                                                                          "--metric-samples", "5000"}}) {
    std::vector<std::string> args{"compress", a, "-o", dir.file("t.h5")};
    args.insert(args.end(), target.begin(), target.end());
    const auto refused = run_gimforge(args);
    EXPECT_EQ(refused.exit_code, 2) << target.front() << ": " << refused.err;
    EXPECT_FALSE(std::filesystem::exists(dir.file("t.h5")));
  }
  const auto none = run_gimforge({"compress", a, "-o", dir.file("n.h5")});
  EXPECT_EQ(none.exit_code, 1);
  EXPECT_NE(none.err.find("needs exactly one target"), std::string::npos) << none.err;
  const auto again = run_gimforge({"compress", c, "--bytes", "3000", "-o", dir.file("r.h5")});
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_NE(again.err.find("already coded"), std::string::npos) << again.err;
  const auto onto = run_gimforge({"compress", a, "--bytes", "3000", "-o", a});
  EXPECT_EQ(onto.exit_code, 1);
  EXPECT_FALSE(std::filesystem::exists(dir.file("s.h5")));
}

TEST(CliCompress, BatchStoresCompressedItemsThatDecompressReads) {
  TempDir dir;
  std::filesystem::create_directories(dir.file("in"));
  std::filesystem::copy_file(kData + "/fist.ply", dir.file("in/fist.ply"));
  std::filesystem::copy_file(kData + "/cathead.ply", dir.file("in/cathead.ply"));
  const std::string job = dir.file("job.toml");
  {
    std::ofstream f(job);
    f << "[[collection]]\ninput = \"" << dir.file("in") << "\"\n\n"
      << "[[output]]\nmethod = \"gim\"\nsize = 65\ncodec = \"wavelet\"\nrate = 4000\n\n"
      << "[[output]]\nmethod = \"gim\"\nsize = 65\ncodec = \"quant12\"\n";
  }
  const auto r = run_gimforge({"-q", "batch", "--job", job, "--metric-samples", "20000", "-o", dir.file("b.h5")}, 600);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  {
    const gimforge::io::Archive a = gimforge::io::Archive::open(dir.file("b.h5"));
    const auto out = a.root().open_group("batch/gim_65_wavelet4000");
    EXPECT_EQ(out.attribute<std::string>("codec"), "wavelet");
    const std::vector<double> bytes = out.open_dataset("metrics/compressed_bytes").read<double>();
    ASSERT_EQ(bytes.size(), 2u);
    for (const double b : bytes) EXPECT_LE(b, 4000.0);
    // Counted again in the merged archive: the merge adds nothing to an item.
    for (const char* k : {"0", "1"}) EXPECT_LE(gimforge::io::stored_bytes(out.open_group(std::string("items/") + k)), 4000u);
    EXPECT_TRUE(out.exists("items/0/geometry_code"));
    EXPECT_TRUE(a.root().exists("batch/gim_65_quant12/items/1/geometry"));
  }
  // The example loader gives a compressed item's sideband (items/<k>/sideband; it returned None there).
  const auto py = run_process({GIMFORGE_PYTHON, "-c",
                               "import sys, h5py, numpy as np; sys.path.insert(0, sys.argv[1]); from load_archive import GimforgeDataset\n"
                               "for out in ('gim_65_quant12', 'gim_65_wavelet4000'):\n"
                               "    ds = GimforgeDataset(sys.argv[2], out)\n"
                               "    for i in range(len(ds)):\n"
                               "        rows, units = ds.sideband(i)\n"
                               "        item = h5py.File(sys.argv[2], 'r')[f'batch/{out}/items/{i}']\n"
                               "        assert units == 64 and np.array_equal(rows, item['sideband'][()]), (out, i, rows)",
                               std::string(GIMFORGE_TESTS_SOURCE_DIR) + "/../examples", dir.file("b.h5")});
  EXPECT_EQ(py.exit_code, 0) << py.err << py.out;
  const auto d = run_gimforge({"decompress", dir.file("b.h5"), "-o", dir.file("d.h5")});
  ASSERT_EQ(d.exit_code, 0) << d.err;
  EXPECT_NE(d.out.find("gim/gim_65_wavelet4000.1"), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("gim/gim_65_quant12.0"), std::string::npos) << d.out;
  const auto rec = run_gimforge({"reconstruct", dir.file("d.h5"), "--name", "gim/gim_65_wavelet4000.0", "-o", dir.file("r.ply")});
  ASSERT_EQ(rec.exit_code, 0) << rec.err;
  EXPECT_EQ(mesh_info(dir.file("r.ply")).at("components"), 1);
  // The options are checked before any work.
  const auto bad = run_gimforge({"batch", "--input", dir.file("in"), "--method", "relief", "--codec", "j2k", "--rate", "4000",
                                 "-o", dir.file("x.h5")});
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("--codec is for the image methods gim, sphere and mcgim"), std::string::npos) << bad.err;
  // With --job every option of the single output is a usage error: the job file's tables set them (--size,
  // --method, --label were once ignored without a word, --codec refused with exit 1).
  for (const std::vector<std::string>& extra : std::vector<std::vector<std::string>>{
           {"--codec", "wavelet", "--rate", "4000"}, {"--size", "129"}, {"--method", "gim"}, {"--label", "none"},
           {"--texture", "8"}}) {
    std::vector<std::string> args{"batch", "--job", job, "-o", dir.file("z.h5")};
    args.insert(args.end(), extra.begin(), extra.end());
    const auto withjob = run_gimforge(args);
    EXPECT_EQ(withjob.exit_code, 2) << extra.front();
    EXPECT_NE(withjob.err.find(extra.front() + ": describes the single output of --input or --list; a job file sets it"),
              std::string::npos)
        << withjob.err;
    EXPECT_FALSE(std::filesystem::exists(dir.file("z.h5")));
  }
  // Decompressing into an archive that already holds the names is refused before any work.
  const auto twice = run_gimforge({"decompress", dir.file("b.h5"), "-o", dir.file("d.h5")});
  EXPECT_EQ(twice.exit_code, 1);
  EXPECT_NE(twice.err.find("already holds"), std::string::npos) << twice.err;
  const auto norate = run_gimforge({"batch", "--input", dir.file("in"), "--codec", "wavelet", "-o", dir.file("y.h5")});
  EXPECT_NE(norate.exit_code, 0);
  EXPECT_NE(norate.err.find("needs --rate"), std::string::npos) << norate.err;
}

TEST(CliCompress, MultiChartImagesAreQuantizedAndCodedAndStayWatertight) {
  TempDir dir;
  const std::string a = dir.file("m.h5");
  const auto conv = run_gimforge({"-q", "convert", kData + "/fist.ply", "--method", "mcgim", "--samples", "16384", "--charts",
                                  "16", "--metric-samples", "20000", "-o", a},
                                 300);
  ASSERT_EQ(conv.exit_code, 0) << conv.err;
  // 12-bit quantization: equal samples stay equal, no fusing needed.
  const auto q = run_gimforge({"compress", a, "--codec", "quant12", "--metric-samples", "20000", "--json", "-o", dir.file("q.h5")});
  ASSERT_EQ(q.exit_code, 0) << q.err;
  const nlohmann::json qi = nlohmann::json::parse(q.out).at("items")[0];
  EXPECT_EQ(qi.at("item"), "mcgim/fist");
  EXPECT_GT(qi.at("surface_psnr").get<double>(), 75.0) << qi.dump();
  EXPECT_LT(qi.at("bytes").get<std::uint64_t>(), qi.at("bytes_before").get<std::uint64_t>() / 2) << qi.dump();
  // JPEG 2000 at a byte budget (auto: the one codec for a rectangle), everything counted.
  const std::string c = dir.file("c.h5");
  const auto j = run_gimforge({"compress", a, "--bytes", "40000", "--metric-samples", "20000", "--json", "-o", c});
  ASSERT_EQ(j.exit_code, 0) << j.err;
  const nlohmann::json ji = nlohmann::json::parse(j.out).at("items")[0];
  EXPECT_EQ(ji.at("codec"), "j2k");
  EXPECT_LE(ji.at("bytes").get<std::uint64_t>(), 40000u);
  EXPECT_GT(ji.at("surface_psnr").get<double>(), 75.0) << ji.dump();  // the charts' quadrics coded apart (88.7 dB)
  for (const std::string& archive : {dir.file("q.h5"), c}) {
    const std::string ply = archive + ".ply";
    const auto rec = run_gimforge({"reconstruct", archive, "-o", ply});
    ASSERT_EQ(rec.exit_code, 0) << rec.err;
    const nlohmann::json t = mesh_info(ply);
    EXPECT_EQ(t.at("boundary_loops"), 0) << archive;  // the zipper fused after decoding
    EXPECT_EQ(t.at("components"), 1) << archive;
  }
  {  // The decoded clusters are bit-identical, and the structure is the convert's.
    const gimforge::io::Archive in = gimforge::io::Archive::open(a), coded = gimforge::io::Archive::open(c);
    const gimforge::MultiChartImage original = gimforge::io::read_multichart_image(in, "fist");
    const gimforge::MultiChartImage decoded = gimforge::io::read_multichart_image(coded, "fist");
    EXPECT_EQ(decoded.mask, original.mask);
    EXPECT_EQ(decoded.chart, original.chart);
    EXPECT_EQ(decoded.unified, original.unified);
    std::size_t zippered = 0;
    for (std::size_t s = 0; s < decoded.samples(); ++s)
      if (decoded.mask[s] && decoded.unified[s] != s) {
        ++zippered;
        for (std::size_t k = 0; k < 3; ++k) ASSERT_EQ(decoded.positions[3 * s + k], decoded.positions[3 * decoded.unified[s] + k]);
      }
    EXPECT_GT(zippered, 100u);
  }
  const auto preview = run_gimforge({"preview", c, "-o", dir.file("png")});
  ASSERT_EQ(preview.exit_code, 0) << preview.err;
  EXPECT_TRUE(std::filesystem::exists(dir.file("png/fist_mcgim_normals.png")));  // recomputed: compress drops normals
  const auto d = run_gimforge({"decompress", c, "-o", dir.file("d.h5")});
  ASSERT_EQ(d.exit_code, 0) << d.err;
  EXPECT_NE(d.out.find("mcgim/fist (float32)"), std::string::npos) << d.out;
  EXPECT_EQ(run_gimforge({"reconstruct", dir.file("d.h5"), "-o", dir.file("d.ply")}).exit_code, 0);
  // The wavelet coder takes square images only; a damaged zipper is one line.
  const auto w = run_gimforge({"compress", a, "--codec", "wavelet", "--bytes", "40000", "-o", dir.file("w.h5")});
  EXPECT_EQ(w.exit_code, 1);
  EXPECT_NE(w.err.find("square images"), std::string::npos) << w.err;
  EXPECT_FALSE(std::filesystem::exists(dir.file("w.h5")));
  {
    gimforge::io::Archive archive = gimforge::io::Archive::open(c, gimforge::h5::OpenMode::kReadWrite);
    gimforge::h5::Dataset z = archive.root().open_dataset("mcgim/fist/zipper");
    std::vector<std::int32_t> rows = z.read<std::int32_t>();
    rows[1] = 1 << 30;
    z.write(rows);
    archive.close();
  }
  const auto bad = run_gimforge({"reconstruct", c, "-o", dir.file("x.ply")});
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("zipper row 0 names a sample outside"), std::string::npos) << bad.err;
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
  // A coded item's structure decides where the decoded values go: damage that a reader could not see from the
  // positions (a zipper row naming another defined sample, another valid chart id, the quadrics missing) is
  // refused by its checksum, not read into a wrong surface.
  for (int damage = 0; damage < 3; ++damage) {
    const std::string damaged = dir.file(std::array<const char*, 3>{"s0.h5", "s1.h5", "s2.h5"}[static_cast<std::size_t>(damage)]);
    ASSERT_EQ(run_gimforge({"compress", a, "--bytes", "40000", "--no-metric", "-o", damaged}).exit_code, 0);
    {
      gimforge::io::Archive archive = gimforge::io::Archive::open(damaged, gimforge::h5::OpenMode::kReadWrite);
      gimforge::h5::Group g = archive.root().open_group("mcgim/fist");
      if (damage == 0) {
        gimforge::h5::Dataset z = g.open_dataset("zipper");
        std::vector<std::int32_t> rows = z.read<std::int32_t>();
        rows[1] = rows[3];  // another representative, defined and its own
        z.write(rows);
      } else if (damage == 1) {
        gimforge::h5::Dataset ch = g.open_dataset("chart");
        std::vector<std::int32_t> ids = ch.read<std::int32_t>();
        const auto s = static_cast<std::size_t>(std::find_if(ids.begin(), ids.end(), [](std::int32_t v) { return v == 3; }) - ids.begin());
        ids[s] = 4;
        ch.write(ids);
      } else {
        ASSERT_EQ(H5Ldelete(g.id(), "chart_planes", H5P_DEFAULT), 0);
      }
    }
    const auto r = run_gimforge({"reconstruct", damaged, "-o", dir.file("s.ply")});
    EXPECT_EQ(r.exit_code, 1) << damage;
    EXPECT_NE(r.err.find(damage == 2 ? "no dataset 'chart_planes'" : "structure checksum mismatch"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  // So are chart maps that are not finite, and chart maps beside positions that are not coded.
  const std::string p = dir.file("p.h5");
  ASSERT_EQ(run_gimforge({"compress", a, "--bytes", "40000", "--no-metric", "-o", p}).exit_code, 0);
  {
    gimforge::io::Archive archive = gimforge::io::Archive::open(p, gimforge::h5::OpenMode::kReadWrite);
    gimforge::h5::Dataset planes = archive.root().open_dataset("mcgim/fist/chart_planes");
    std::vector<float> values = planes.read<float>();
    values[5] = std::numeric_limits<float>::infinity();
    planes.write(values);
    gimforge::io::Archive quantized = gimforge::io::Archive::open(dir.file("q.h5"), gimforge::h5::OpenMode::kReadWrite);
    quantized.root().open_group("mcgim/fist").write_dataset("chart_planes", {values.size() / gimforge::kPlaneFloats, gimforge::kPlaneFloats},
                                                           planes.read<float>());
  }
  const auto inf = run_gimforge({"reconstruct", p, "-o", dir.file("y.ply")});
  EXPECT_EQ(inf.exit_code, 1);
  EXPECT_NE(inf.err.find("'chart_planes' holds a value that is not finite"), std::string::npos) << inf.err;
  const auto stray = run_gimforge({"reconstruct", dir.file("q.h5"), "-o", dir.file("z.ply")});
  EXPECT_EQ(stray.exit_code, 1);
  EXPECT_NE(stray.err.find("'chart_planes' beside positions that are not coded"), std::string::npos) << stray.err;
}

TEST(CliCompress, ACodedMultiChartImageKeepsTheTopologyOfTheStoredOne) {
  // The fist at 8 charts and 4,096 samples has a zipper cluster of ~100 samples that sealed three samples of
  // a chart: their faces cancel with the stored positions' diagonals. Decoded at 4,000–5,000 bytes, diagonals
  // re-chosen from the decoded positions turned, and a 4-face closed piece pinched off beside the surface.
  // The pinned quads' stored splits (zipper_diagonals) give the decoded image the stored image's faces.
  TempDir dir;
  const std::string a = dir.file("m.h5");
  ASSERT_EQ(run_gimforge({"-q", "convert", kData + "/fist.ply", "--method", "mcgim", "--samples", "4096", "--charts", "8",
                          "--no-metric", "-o", a}, 300).exit_code, 0);
  ASSERT_EQ(run_gimforge({"reconstruct", a, "-o", dir.file("m.ply")}).exit_code, 0);
  const nlohmann::json stored = mesh_info(dir.file("m.ply"));
  ASSERT_EQ(stored.at("components"), 1);
  for (const char* bytes : {"4000", "5000", "8000"}) {
    const std::string c = dir.file(std::string("c") + bytes + ".h5"), ply = c + ".ply";
    const auto r = run_gimforge({"compress", a, "--codec", "j2k", "--bytes", bytes, "--no-metric", "-o", c});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    ASSERT_EQ(run_gimforge({"reconstruct", c, "-o", ply}).exit_code, 0);
    const nlohmann::json t = mesh_info(ply);
    EXPECT_EQ(t.at("components"), 1) << bytes;
    EXPECT_EQ(t.at("vertices"), stored.at("vertices")) << bytes;
    EXPECT_EQ(t.at("faces"), stored.at("faces")) << bytes;
    EXPECT_EQ(t.at("boundary_edges"), 0) << bytes;
    // decompress keeps the splits with the float32 positions
    const std::string d = c + ".d.h5";
    ASSERT_EQ(run_gimforge({"decompress", c, "-o", d}).exit_code, 0);
    ASSERT_EQ(run_gimforge({"reconstruct", d, "-o", d + ".ply"}).exit_code, 0);
    EXPECT_EQ(mesh_info(d + ".ply").at("faces"), stored.at("faces")) << bytes;
  }
}

TEST(CliCompress, BatchStoresCompressedMultiChartItemsThatTheLoaderAndDecompressRead) {
  TempDir dir;
  std::filesystem::create_directories(dir.file("in"));
  std::filesystem::copy_file(kData + "/fist.ply", dir.file("in/fist.ply"));
  std::filesystem::copy_file(kData + "/kitten.ply", dir.file("in/kitten.ply"));
  for (const std::vector<std::string>& codec : {std::vector<std::string>{"--codec", "quant12"},
                                                std::vector<std::string>{"--codec", "j2k", "--rate", "40000"}}) {
    std::vector<std::string> args{"-q", "batch", "--input", dir.file("in"), "--method", "mcgim", "--samples", "16384",
                                  "--charts", "16", "--metric-samples", "20000", "-o", dir.file(codec[1] + ".h5")};
    args.insert(args.end(), codec.begin(), codec.end());
    const auto r = run_gimforge(args, 600);
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  const std::string examples = std::string(GIMFORGE_TESTS_SOURCE_DIR) + "/../examples";
  // The loader dequantizes a quantized item (the positions within two 12-bit steps of the float32 conversion) and
  // names decompress for a coded one.
  const auto py = run_process({GIMFORGE_PYTHON, "-c",
                               "import sys, numpy as np; sys.path.insert(0, sys.argv[1]); from load_archive import GimforgeDataset; "
                               "item = GimforgeDataset(sys.argv[2])[0]; g = item['mcgim']['geometry']; m = item['mcgim']['mask'] == 1; "
                               "assert g.dtype == np.float64 and np.isfinite(g[m]).all() and np.isnan(g[~m]).all(); "
                               "span = np.nanmax(g[m], axis=0) - np.nanmin(g[m], axis=0); assert (span > 0.1).all() and (span < 10).all(), span; "
                               "assert item['attrs']['compressed_psnr'] > 75 if 'compressed_psnr' in item['attrs'] else True\n"
                               "try:\n    GimforgeDataset(sys.argv[3])[0]\n    raise SystemExit('coded item read')\n"
                               "except ValueError as e:\n    assert 'gimforge decompress' in str(e), e",
                               examples, dir.file("quant12.h5"), dir.file("j2k.h5")});
  EXPECT_EQ(py.exit_code, 0) << py.err << py.out;
  const auto d = run_gimforge({"decompress", dir.file("j2k.h5"), "-o", dir.file("d.h5")});
  ASSERT_EQ(d.exit_code, 0) << d.err;
  EXPECT_NE(d.out.find("mcgim/mcgim_16384_16_j2k40000.1"), std::string::npos) << d.out;
  const auto rec = run_gimforge({"reconstruct", dir.file("d.h5"), "--name", "mcgim/mcgim_16384_16_j2k40000.0", "-o", dir.file("r.ply")});
  ASSERT_EQ(rec.exit_code, 0) << rec.err;
  EXPECT_EQ(mesh_info(dir.file("r.ply")).at("boundary_loops"), 0);
  const auto wavelet = run_gimforge({"batch", "--input", dir.file("in"), "--method", "mcgim", "--codec", "wavelet", "--rate",
                                     "40000", "-o", dir.file("x.h5")});
  EXPECT_NE(wavelet.exit_code, 0);
  EXPECT_NE(wavelet.err.find("not a multi-chart rectangle"), std::string::npos) << wavelet.err;
}

TEST(CliCompress, ALinkOutOfACodedItemIsRefusedNotFollowed) {
  // ls counts a coded item's stored bytes by walking its group: an external link there to a FIFO hung ls and
  // the pre-check of `convert -o` (the walk looked at the object behind the link before its kind); one to
  // another archive opened that file. Both are refused as every other reader refuses links.
  TempDir dir;
  const std::string a = converted(dir), c = dir.file("c.h5"), fifo = dir.file("fifo");
  ASSERT_EQ(run_gimforge({"-q", "compress", a, "--name", "gim/fist", "--codec", "wavelet", "--bytes", "5000", "--no-metric",
                          "-o", c})
                .exit_code,
            0);
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  {
    const hid_t f = H5Fopen(c.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    ASSERT_GE(H5Lcreate_external(fifo.c_str(), "/x", f, "gim/fist/zz", H5P_DEFAULT, H5P_DEFAULT), 0);
    H5Fclose(f);
  }
  const auto ls = run_gimforge({"ls", c}, 30);
  EXPECT_EQ(ls.exit_code, 1) << ls.err;  // listed, then counted on stderr
  EXPECT_NE(ls.err.find("1 item is unreadable (listed above)"), std::string::npos) << ls.err;
  EXPECT_NE(ls.out.find("unreadable: "), std::string::npos) << ls.out;
  EXPECT_NE(ls.out.find("/gim/fist/zz is an external link"), std::string::npos) << ls.out;
  const auto into = run_gimforge({"convert", kData + "/tetra.obj", "--method", "relief", "--grid", "1", "--no-metric", "-o", c}, 30);
  EXPECT_EQ(into.exit_code, 1);
  EXPECT_NE(into.err.find("follows only hard links"), std::string::npos) << into.err;
}

TEST(CliCompress, RunningOutOfSpaceIsAnErrorNotADamagedArchive) {
  // A chunked dataset's last chunks reach the file when it closes, and that close's failure was dropped:
  // `decompress` on a full disk wrote an archive of zeros with exit 0 (and `compress` said "slist already
  // enabled?"). The file-size limit (ulimit -f, SIGXFSZ ignored) fails writes as a full disk does.
  TempDir dir;
  const std::string a = converted(dir);
  const std::string coded = dir.file("coded.h5");
  ASSERT_EQ(run_gimforge({"-q", "compress", a, "--codec", "quant12", "-o", coded}).exit_code, 0);
  const auto limited = [](std::uintmax_t limit_bytes, std::vector<std::string> args) {
    args.insert(args.begin(), "-q");
    return gimforge::test::run_gimforge_after("ulimit -f " + std::to_string(limit_bytes / 512) + "; trap '' XFSZ", args);
  };
  const auto size = [](const std::string& path) { return std::filesystem::file_size(path); };
  const std::string out = dir.file("out.h5");
  for (const auto& [args, full] :
       {std::pair{std::vector<std::string>{"decompress", coded, "-o", out}, size(a)},
        std::pair{std::vector<std::string>{"compress", a, "--codec", "quant12", "-o", out}, size(coded)},
        std::pair{std::vector<std::string>{"compress", a, "--codec", "j2k", "--bytes", "30000", "-o", out}, size(coded)}}) {
    for (const std::uintmax_t limit : {full / 4, full / 2, 3 * full / 4}) {
      SCOPED_TRACE(args[0] + " " + args[2] + " " + std::to_string(limit));
      const auto r = limited(limit, args);
      if (r.exit_code == 0) {  // it fitted: then the archive is whole
        for (const char* item : {"gim/fist", "spherical/fist"})
          EXPECT_EQ(run_gimforge({"reconstruct", out, "--name", item, "-o", dir.file("r.ply")}).exit_code, 0) << item;
        std::filesystem::remove(out);
        continue;
      }
      EXPECT_EQ(r.exit_code, 1) << r.err;
      const auto lines = r.err_lines();
      ASSERT_EQ(lines.size(), 1u) << r.err;
      EXPECT_TRUE(lines[0].starts_with("gimforge: error: " + out + ":")) << lines[0];
      EXPECT_NE(lines[0].find("File too large"), std::string::npos) << lines[0];
      EXPECT_FALSE(std::filesystem::exists(out));
    }
  }
}
