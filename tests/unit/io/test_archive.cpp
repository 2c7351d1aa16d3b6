// Tests of the gimforge archive root (io/archive.h): identity attributes, version checks, image datasets.
#include <gtest/gtest.h>

#include "tests/unit/test_support.h"
#include <hdf5.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "gimforge_version.h"
#include "io/archive.h"
#include "kernels/core/errors.h"

namespace fs = std::filesystem;
using namespace gimforge;
using h5::Dims;

namespace {

using gimforge::test::message_of;

class ArchiveTest : public gimforge::test::ScratchDirTest {};

io::CreationInfo sample_info() {
  return {.creator = "gimforge gim --size 64 bunny.ply", .parameters_json = R"({ "size": 64, "method": "gim" })"};
}

/// True for ISO-8601 UTC with seconds: "YYYY-MM-DDTHH:MM:SSZ".
bool is_iso8601_utc(const std::string& text) {
  const std::string pattern = "dddd-dd-ddTdd:dd:ddZ";
  return text.size() == pattern.size() && std::equal(pattern.begin(), pattern.end(), text.begin(), [](char p, char c) {
           return p == 'd' ? (c >= '0' && c <= '9') : p == c;
         });
}


/// Chunk shape and deflate presence, read with the C API.
std::pair<std::vector<hsize_t>, bool> chunk_and_deflate(const h5::Dataset& ds) {
  const hid_t dcpl = H5Dget_create_plist(ds.id());
  std::vector<hsize_t> chunk(8);
  const int rank = H5Pget_layout(dcpl) == H5D_CHUNKED ? H5Pget_chunk(dcpl, 8, chunk.data()) : 0;
  chunk.resize(static_cast<std::size_t>(rank));
  unsigned flags = 0;
  std::size_t n = 0;
  const bool deflate = H5Pget_filter_by_id2(dcpl, H5Z_FILTER_DEFLATE, &flags, &n, nullptr, 0, nullptr, nullptr) >= 0;
  H5Pclose(dcpl);
  H5Eclear2(H5E_DEFAULT);
  return {chunk, deflate};
}

TEST_F(ArchiveTest, CreateThenOpenRoundTripsTheRootAttributes) {
  const fs::path path = file("a.h5");
  { io::Archive a = io::Archive::create(path, sample_info()); }
  const io::Archive a = io::Archive::open(path);
  const io::ArchiveInfo info = a.info();
  EXPECT_EQ(info.format, "gimforge");
  EXPECT_EQ(info.format_version, io::kArchiveFormatVersion);
  EXPECT_EQ(info.gimforge_version, kVersion);
  EXPECT_TRUE(is_iso8601_utc(info.created)) << info.created;
  EXPECT_FALSE(is_iso8601_utc("2024-05-01 12:34:56"));
  EXPECT_EQ(info.creator, "gimforge gim --size 64 bunny.ply");
  EXPECT_EQ(info.creation_parameters, R"({"method":"gim","size":64})");
  EXPECT_EQ(a.path(), path);
  EXPECT_EQ(a.root().path(), "/");
}

TEST_F(ArchiveTest, GivenCreationTimeIsKept) {
  io::CreationInfo info = sample_info();
  info.created = "2020-01-02T03:04:05Z";
  const io::Archive a = io::Archive::create(file("t.h5"), info);
  EXPECT_EQ(a.info().created, "2020-01-02T03:04:05Z");
}

TEST_F(ArchiveTest, InvalidParameterJsonIsRejectedBeforeTheFileIsCreated) {
  io::CreationInfo info = sample_info();
  info.parameters_json = "{not json";
  EXPECT_THROW((void)io::Archive::create(file("j.h5"), info), InvalidInput);
  EXPECT_FALSE(fs::exists(file("j.h5")));
}

TEST_F(ArchiveTest, ReadWriteOpenAddsRepresentationGroups) {
  const fs::path path = file("rw.h5");
  { (void)io::Archive::create(path, sample_info()); }
  {
    io::Archive a = io::Archive::open(path, h5::OpenMode::kReadWrite);
    a.root().require_group("gim/bunny").set_attribute("resolution", 64);
    a.close();
  }
  const io::Archive a = io::Archive::open(path);
  EXPECT_EQ(a.root().open_group("gim/bunny").attribute<std::int64_t>("resolution"), 64);
  EXPECT_THROW(io::Archive::open(path).root().create_group("x"), LibraryError);  // read-only
}

TEST_F(ArchiveTest, PlainHdf5FileIsNotAnArchive) {
  const fs::path path = file("plain.h5");
  { h5::File f = h5::File::create(path); }
  EXPECT_EQ(message_of<IoError>([&] { (void)io::Archive::open(path); }),
            path.string() + ": not a gimforge archive (no 'format' attribute)");
}

TEST_F(ArchiveTest, OtherFormatIsNotAnArchive) {
  const fs::path path = file("other.h5");
  {
    h5::File f = h5::File::create(path);
    f.set_attribute("format", "netcdf");
    f.set_attribute("format_version", 1);
  }
  EXPECT_EQ(message_of<FormatError>([&] { (void)io::Archive::open(path); }),
            path.string() + ": not a gimforge archive (format is 'netcdf')");
}

TEST_F(ArchiveTest, NewerFormatVersionIsRejected) {
  const fs::path path = file("new.h5");
  { io::Archive::create(path, sample_info()).root().set_attribute("format_version", 7); }
  EXPECT_EQ(message_of<IoError>([&] { (void)io::Archive::open(path); }),
            path.string() + ": archive format_version 7 is newer than this gimforge (2)");
}

TEST_F(ArchiveTest, MissingFileAndNonHdf5FileThrowIoError) {
  EXPECT_THROW((void)io::Archive::open(file("absent.h5")), IoError);
  const fs::path text = file("x.h5");
  {
    std::FILE* f = std::fopen(text.c_str(), "w");
    std::fputs("hello", f);
    std::fclose(f);
  }
  const std::string msg = message_of<IoError>([&] { (void)io::Archive::open(text); });
  EXPECT_EQ(msg.rfind(text.string() + ": ", 0), 0u) << msg;
}

TEST_F(ArchiveTest, ImagesAreChunkedCompressedAndRoundTrip) {
  io::Archive a = io::Archive::create(file("img.h5"), sample_info());
  h5::Group g = a.root().create_group("gim/bunny");
  std::vector<float> rgb(300 * 280 * 3);
  for (std::size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<float>(i) * 0.5f;
  const h5::Dataset geometry = io::write_image(g, "geometry", Dims{300, 280, 3}, rgb);
  EXPECT_EQ(geometry.read<float>(), rgb);
  EXPECT_EQ(geometry.dtype(), h5::DType::kFloat32);
  const auto [chunk, deflate] = chunk_and_deflate(geometry);
  EXPECT_EQ(chunk, (std::vector<hsize_t>{256, 256, 3}));
  EXPECT_TRUE(deflate);

  const std::vector<std::uint16_t> q{0, 1, 65535, 42};
  const h5::Dataset normals = io::write_quantized_image(g, "normal_map", Dims{2, 2}, q, 2.0 / 65535, -1.0);
  EXPECT_EQ(normals.read<std::uint16_t>(), q);
  EXPECT_EQ(normals.dtype(), h5::DType::kUInt16);
  EXPECT_DOUBLE_EQ(normals.attribute<double>("scale"), 2.0 / 65535);
  EXPECT_DOUBLE_EQ(normals.attribute<double>("offset"), -1.0);
  EXPECT_EQ(chunk_and_deflate(normals).first, (std::vector<hsize_t>{2, 2}));
}

TEST_F(ArchiveTest, ImageShapeErrorsAndEmptyImages) {
  io::Archive a = io::Archive::create(file("bad.h5"), sample_info());
  const std::vector<float> px(12);
  EXPECT_THROW(io::write_image(a.root(), "flat", Dims{12}, px), InvalidInput);
  EXPECT_THROW(io::write_image(a.root(), "short", Dims{2, 2, 2}, px), InvalidInput);
  const h5::Dataset empty = io::write_image(a.root(), "empty", Dims{0, 4, 3}, std::span<const float>{});
  EXPECT_EQ(empty.shape(), (Dims{0, 4, 3}));
  const h5::Dataset custom = io::write_image(a.root(), "custom", Dims{2, 2, 3}, px, {.chunk = {1, 2, 3}, .deflate = 1});
  EXPECT_EQ(chunk_and_deflate(custom).first, (std::vector<hsize_t>{1, 2, 3}));
}

}  // namespace
