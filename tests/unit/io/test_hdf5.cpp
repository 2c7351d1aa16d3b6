// Tests of the checked HDF5 layer (io/hdf5.h): round trips of every dataset and attribute type, storage
// options as HDF5 records them, hyperslabs, resizable datasets, error messages and silence on stderr.
#include <fcntl.h>
#include <gtest/gtest.h>

#include "tests/unit/test_support.h"
#include <hdf5.h>
#include <unistd.h>

#include <array>
#include <cstring>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "io/hdf5.h"
#include "kernels/core/errors.h"

namespace fs = std::filesystem;
using namespace gimforge;
using h5::Dims;

namespace {

using gimforge::test::message_of;

class Hdf5Test : public gimforge::test::ScratchDirTest {};

/// Redirects file descriptor 2 into a file until finish(), which returns what was written.
class StderrCapture {
 public:
  explicit StderrCapture(fs::path path) : path_(std::move(path)) {
    std::fflush(stderr);
    saved_ = dup(2);
    const int fd = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    dup2(fd, 2);
    close(fd);
  }
  std::string finish() {
    std::fflush(stderr);
    dup2(saved_, 2);
    close(saved_);
    std::ifstream in(path_);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
  }

 private:
  fs::path path_;
  int saved_ = -1;
};

/// Values 0, 1, 2, ... of type T (wrapping for uint8).
template <class T>
std::vector<T> iota_values(std::size_t n) {
  std::vector<T> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<T>(i % 200);
  return v;
}

/// Storage facts read straight from the dataset creation property list with the C API.
struct Storage {
  H5D_layout_t layout = H5D_LAYOUT_ERROR;
  std::vector<hsize_t> chunk;
  bool deflate = false;
  unsigned deflate_level = 0;
  bool shuffle = false;
};

Storage storage_of(const h5::Dataset& ds) {
  Storage s;
  const hid_t dcpl = H5Dget_create_plist(ds.id());
  s.layout = H5Pget_layout(dcpl);
  if (s.layout == H5D_CHUNKED) {
    s.chunk.resize(8);
    s.chunk.resize(static_cast<std::size_t>(H5Pget_chunk(dcpl, 8, s.chunk.data())));
  }
  unsigned flags = 0;
  std::size_t n = 1;
  unsigned level = 0;
  s.deflate = H5Pget_filter_by_id2(dcpl, H5Z_FILTER_DEFLATE, &flags, &n, &level, 0, nullptr, nullptr) >= 0;
  s.deflate_level = level;
  n = 0;
  s.shuffle = H5Pget_filter_by_id2(dcpl, H5Z_FILTER_SHUFFLE, &flags, &n, nullptr, 0, nullptr, nullptr) >= 0;
  H5Pclose(dcpl);
  H5Eclear2(H5E_DEFAULT);  // a missing filter leaves an error on the stack
  return s;
}

/// An HDF5 automatic-error callback printing the stack like HDF5's default does.
herr_t print_stack(hid_t stack, void* stream) { return H5Eprint2(stack, static_cast<FILE*>(stream)); }


// ---- numeric round trips ----------------------------------------------------------------------

template <class T>
class Hdf5NumericTest : public Hdf5Test {};
using NumericTypes = ::testing::Types<std::uint8_t, std::uint16_t, std::int32_t, std::int64_t, float, double,
                                      std::int8_t, std::uint32_t>;
TYPED_TEST_SUITE(Hdf5NumericTest, NumericTypes);

TYPED_TEST(Hdf5NumericTest, WholeDatasetRoundTripKeepsValuesShapeAndType) {
  const auto values = iota_values<TypeParam>(24);
  const fs::path path = this->file("numeric.h5");
  {
    h5::File f = h5::File::create(path);
    f.write_dataset("data/values", Dims{2, 3, 4}, values);
  }
  h5::File f = h5::File::open(path);
  const h5::Dataset ds = f.open_dataset("data/values");
  EXPECT_EQ(ds.shape(), (Dims{2, 3, 4}));
  EXPECT_EQ(ds.element_count(), 24u);
  EXPECT_EQ(ds.dtype(), h5::kDTypeOf<TypeParam>);
  EXPECT_EQ(ds.template read<TypeParam>(), values);
}

TYPED_TEST(Hdf5NumericTest, CompressedRoundTrip) {
  const auto values = iota_values<TypeParam>(100);
  h5::File f = h5::File::create(this->file("z.h5"));
  const h5::Dataset ds = f.write_dataset("z", Dims{10, 10}, values, {.chunk = {5, 5}, .deflate = 9, .shuffle = true});
  EXPECT_EQ(ds.template read<TypeParam>(), values);
}

// ---- storage options --------------------------------------------------------------------------

TEST_F(Hdf5Test, ChunkShuffleAndDeflateAreRecordedInTheDcpl) {
  h5::File f = h5::File::create(file("c.h5"));
  const auto values = iota_values<float>(6 * 8 * 3);
  const h5::Dataset ds =
      f.write_dataset("img", Dims{6, 8, 3}, values, {.chunk = {2, 4, 3}, .deflate = 6, .shuffle = true});
  const Storage s = storage_of(ds);
  EXPECT_EQ(s.layout, H5D_CHUNKED);
  EXPECT_EQ(s.chunk, (std::vector<hsize_t>{2, 4, 3}));
  EXPECT_TRUE(s.deflate);
  EXPECT_EQ(s.deflate_level, 6u);
  EXPECT_TRUE(s.shuffle);
}

TEST_F(Hdf5Test, PlainDatasetIsContiguousAndUnfiltered) {
  h5::File f = h5::File::create(file("p.h5"));
  const h5::Dataset ds = f.write_dataset("plain", Dims{4}, std::vector<double>{1, 2, 3, 4});
  const Storage s = storage_of(ds);
  EXPECT_EQ(s.layout, H5D_CONTIGUOUS);
  EXPECT_FALSE(s.deflate);
  EXPECT_FALSE(s.shuffle);
}

TEST_F(Hdf5Test, CompressionWithoutChunkShapePicksOneWithinTheExtents) {
  h5::File f = h5::File::create(file("d.h5"));
  const h5::Dataset ds = f.create_dataset("big", h5::DataType::of<float>(), Dims{1024, 1024, 3}, {.deflate = 1});
  const Storage s = storage_of(ds);
  ASSERT_EQ(s.layout, H5D_CHUNKED);
  ASSERT_EQ(s.chunk.size(), 3u);
  EXPECT_LE(s.chunk[0] * s.chunk[1] * s.chunk[2] * sizeof(float), 1u << 20);
  EXPECT_LE(s.chunk[0], 1024u);
  EXPECT_TRUE(s.deflate);
  EXPECT_FALSE(s.shuffle);
}

TEST_F(Hdf5Test, EmptyFixedDatasetIsStoredContiguous) {
  h5::File f = h5::File::create(file("e.h5"));
  const h5::Dataset ds = f.write_dataset("empty", Dims{0, 3}, std::vector<float>{}, {.deflate = 4});
  EXPECT_EQ(storage_of(ds).layout, H5D_CONTIGUOUS);
  EXPECT_TRUE(ds.read<float>().empty());
}

TEST_F(Hdf5Test, InconsistentOptionsThrowInvalidInput) {
  h5::File f = h5::File::create(file("o.h5"));
  const auto type = h5::DataType::of<float>();
  EXPECT_THROW((void)f.create_dataset("a", type, Dims{4, 4}, {.deflate = 10}), InvalidInput);
  EXPECT_THROW((void)f.create_dataset("b", type, Dims{4, 4}, {.chunk = {2}}), InvalidInput);
  EXPECT_THROW((void)f.create_dataset("c", type, Dims{4, 4}, {.chunk = {8, 2}}), InvalidInput);
  EXPECT_THROW((void)f.create_dataset("d", type, Dims{}, {}), InvalidInput);
  EXPECT_FALSE(f.exists("a"));
}

// ---- strings ----------------------------------------------------------------------------------

TEST_F(Hdf5Test, VariableAndFixedLengthStringDatasetsRoundTrip) {
  const std::vector<std::string> names{"bunny", "", "Zürich", "a longer name with spaces"};
  const fs::path path = file("s.h5");
  {
    h5::File f = h5::File::create(path);
    f.write_strings("var", names);
    f.write_strings("fixed", names, h5::DataType::fixed_string(32));
  }
  h5::File f = h5::File::open(path);
  EXPECT_EQ(f.open_dataset("var").read_strings(), names);
  EXPECT_EQ(f.open_dataset("fixed").read_strings(), names);
  EXPECT_EQ(f.open_dataset("var").dtype(), h5::DType::kString);
}

TEST_F(Hdf5Test, TooLongFixedStringThrowsInvalidInput) {
  h5::File f = h5::File::create(file("s.h5"));
  const std::vector<std::string> names{"abcdef"};
  EXPECT_THROW(f.write_strings("fixed", names, h5::DataType::fixed_string(3)), InvalidInput);
}

TEST_F(Hdf5Test, NumbersAndStringsDoNotMix) {
  h5::File f = h5::File::create(file("m.h5"));
  const h5::Dataset strings = f.write_strings("names", std::vector<std::string>{"x"});
  const h5::Dataset numbers = f.write_dataset("values", Dims{1}, std::vector<float>{1});
  EXPECT_THROW((void)strings.read<float>(), FormatError);
  EXPECT_THROW((void)numbers.read_strings(), FormatError);
}

// ---- hyperslabs and resizable datasets ---------------------------------------------------------

TEST_F(Hdf5Test, HyperslabBlocksAssembleTheWholeDataset) {
  h5::File f = h5::File::create(file("h.h5"));
  h5::Dataset ds = f.create_dataset("grid", h5::DataType::of<std::int32_t>(), Dims{8, 6}, {.chunk = {4, 3}});
  for (std::uint64_t block = 0; block < 4; ++block) {  // four 2 x 6 row blocks, values = global index
    std::vector<std::int32_t> rows(12);
    for (std::size_t i = 0; i < rows.size(); ++i) rows[i] = static_cast<std::int32_t>(block * 12 + i);
    ds.write_slab(Dims{block * 2, 0}, Dims{2, 6}, rows);
  }
  EXPECT_EQ(ds.read<std::int32_t>(), iota_values<std::int32_t>(48));
  EXPECT_EQ(ds.read_slab<std::int32_t>(Dims{3, 2}, Dims{2, 2}), (std::vector<std::int32_t>{20, 21, 26, 27}));
  ds.write_slab(Dims{8, 0}, Dims{0, 6}, std::vector<std::int32_t>{});  // an empty block is allowed
}

TEST_F(Hdf5Test, BadHyperslabsThrowInvalidInput) {
  h5::File f = h5::File::create(file("h.h5"));
  h5::Dataset ds = f.create_dataset("grid", h5::DataType::of<float>(), Dims{4, 4});
  EXPECT_THROW(ds.write_slab(Dims{3, 0}, Dims{2, 4}, std::vector<float>(8)), InvalidInput);  // leaves the dataset
  EXPECT_THROW(ds.write_slab(Dims{0, 0}, Dims{2, 4}, std::vector<float>(7)), InvalidInput);  // wrong count
  EXPECT_THROW(ds.write_slab(Dims{0}, Dims{2}, std::vector<float>(2)), InvalidInput);        // wrong rank
  EXPECT_THROW(ds.write(std::vector<float>(15)), InvalidInput);
}

TEST_F(Hdf5Test, ResizableDatasetGrowsByAppendedRows) {
  const fs::path path = file("r.h5");
  {
    h5::File f = h5::File::create(path);
    h5::Dataset ds = f.create_dataset("rows", h5::DataType::of<double>(), Dims{0, 3}, {.resizable = true});
    ds.append(std::vector<double>{0, 1, 2, 3, 4, 5});
    ds.append(std::vector<double>{6, 7, 8});
    EXPECT_THROW(ds.append(std::vector<double>{1, 2}), InvalidInput);  // not a whole row
  }
  h5::File f = h5::File::open(path, h5::OpenMode::kReadWrite);
  h5::Dataset ds = f.open_dataset("rows");
  EXPECT_EQ(ds.shape(), (Dims{3, 3}));
  EXPECT_EQ(ds.read<double>(), iota_values<double>(9));
  ds.extend(5);
  EXPECT_EQ(ds.shape(), (Dims{5, 3}));
  EXPECT_EQ(storage_of(ds).layout, H5D_CHUNKED);
}

TEST_F(Hdf5Test, ExtendingAFixedDatasetThrowsLibraryError) {
  h5::File f = h5::File::create(file("r.h5"));
  h5::Dataset ds = f.write_dataset("fixed", Dims{2}, std::vector<float>{1, 2});
  EXPECT_THROW(ds.extend(3), LibraryError);
}

// ---- attributes -------------------------------------------------------------------------------

TEST_F(Hdf5Test, AttributesOfEveryTypeRoundTripOnFileGroupAndDataset) {
  const fs::path path = file("a.h5");
  const std::vector<double> doubles{0.5, -1.25, 1e300};
  const std::vector<std::int64_t> ints{-3, 0, 1LL << 40};
  auto annotate = [&](h5::Object& o) {
    o.set_attribute("text", "héllo");
    o.set_attribute("count", 42);
    o.set_attribute("big", std::int64_t{1} << 50);
    o.set_attribute("ratio", 0.25);
    o.set_attribute("single", 1.5f);
    o.set_attribute("doubles", doubles);
    o.set_attribute("ints", ints);
    o.set_attribute("none", std::vector<double>{});
  };
  {
    h5::File f = h5::File::create(path);
    h5::Group g = f.create_group("g");
    h5::Dataset ds = g.write_dataset("d", Dims{1}, std::vector<float>{1});
    annotate(f);
    annotate(g);
    annotate(ds);
    f.set_attribute("count", 43);  // overwrite
  }
  h5::File f = h5::File::open(path);
  const h5::Group g = f.open_group("g");
  const h5::Dataset ds = g.open_dataset("d");
  for (const h5::Object* o : std::array<const h5::Object*, 3>{&f, &g, &ds}) {
    SCOPED_TRACE(o->path());
    EXPECT_EQ(o->attribute<std::string>("text"), "héllo");
    EXPECT_EQ(o->attribute<std::int64_t>("count"), o == &f ? 43 : 42);
    EXPECT_EQ(o->attribute<std::int64_t>("big"), std::int64_t{1} << 50);
    EXPECT_EQ(o->attribute<double>("ratio"), 0.25);
    EXPECT_EQ(o->attribute<double>("single"), 1.5);
    EXPECT_EQ(o->attribute<std::vector<double>>("doubles"), doubles);
    EXPECT_EQ(o->attribute<std::vector<std::int64_t>>("ints"), ints);
    EXPECT_TRUE(o->attribute<std::vector<double>>("none").empty());
    EXPECT_TRUE(o->has_attribute("text"));
    EXPECT_FALSE(o->has_attribute("absent"));
    EXPECT_EQ(o->attribute_names(),
              (std::vector<std::string>{"big", "count", "doubles", "ints", "none", "ratio", "single", "text"}));
  }
}

// A damaged archive must not decode to a wrong surface: a quantized image's `scale` with one flipped bit
// would (the geometry's own bytes are deflated and carry zlib's checksum, attributes do not). Numeric
// attribute values sit in version-2 object headers, whose checksum HDF5 verifies, on the root, a group and
// a dataset, also beyond the 8 attributes after which HDF5 would by default move them into unchecked heaps.
TEST_F(Hdf5Test, AFlippedBitInANumericAttributeIsACheckedErrorNotAWrongValue) {
  const fs::path path = file("c.h5");
  const auto value = [](int object, int k) { return 1.0 + 0.001 * (100 * object + k); };  // distinct patterns
  {
    h5::File f = h5::File::create(path);
    h5::Group g = f.create_group("gim").create_group("item");
    h5::Dataset ds = g.write_dataset("geometry", Dims{2}, std::vector<std::uint16_t>{1, 2});
    int object = 0;
    for (h5::Object* o : std::array<h5::Object*, 3>{&f, &g, &ds}) {
      for (int k = 0; k < 12; ++k) o->set_attribute(fmt::format("a{:02}", k), value(object, k));
      ++object;
    }
  }
  std::stringstream whole;
  whole << std::ifstream(path, std::ios::binary).rdbuf();
  const std::string bytes = whole.str();
  const auto read = [](const fs::path& p, int object, int k) {
    const h5::File f = h5::File::open(p);
    const std::string key = fmt::format("a{:02}", k);
    if (object == 0) return f.attribute<double>(key);
    const h5::Group g = f.open_group("gim/item");
    return object == 1 ? g.attribute<double>(key) : g.open_dataset("geometry").attribute<double>(key);
  };
  for (int object = 0; object < 3; ++object)
    for (int k : {0, 11}) {
      SCOPED_TRACE(fmt::format("object {} attribute a{:02}", object, k));
      const double v = value(object, k);
      std::string pattern(sizeof v, '\0');
      std::memcpy(pattern.data(), &v, sizeof v);
      const std::size_t at = bytes.find(pattern);
      ASSERT_NE(at, std::string::npos);
      ASSERT_EQ(bytes.find(pattern, at + 1), std::string::npos);
      ASSERT_EQ(read(path, object, k), v);
      std::string damaged = bytes;
      damaged[at] = static_cast<char>(damaged[at] ^ 0x01);  // the lowest mantissa bit: a plausible value
      const fs::path copy = file(fmt::format("c{}{}.h5", object, k));
      std::ofstream(copy, std::ios::binary) << damaged;
      const std::string message = message_of<Error>([&] { (void)read(copy, object, k); });
      EXPECT_NE(message.find("checksum"), std::string::npos) << message;
    }
}

TEST_F(Hdf5Test, WrongTypeAttributeReadNamesAttributeObjectAndTypes) {
  h5::File f = h5::File::create(file("t.h5"));
  f.set_attribute("format_version", "1");
  f.set_attribute("pair", std::vector<std::int64_t>{1, 2});
  const std::string msg = message_of<FormatError>([&] { (void)f.attribute<std::int64_t>("format_version"); });
  EXPECT_NE(msg.find("attribute 'format_version' of / is a string, expected an integer"), std::string::npos) << msg;
  EXPECT_EQ(msg.rfind(file("t.h5").string(), 0), 0u) << msg;
  EXPECT_THROW((void)f.attribute<double>("pair"), FormatError);
  const std::string many = message_of<FormatError>([&] { (void)f.attribute<std::int64_t>("pair"); });
  EXPECT_NE(many.find("holds 2 values, expected one"), std::string::npos) << many;
  const std::string missing = message_of<FormatError>([&] { (void)f.attribute<std::string>("nope"); });
  EXPECT_NE(missing.find("/ has no attribute 'nope'"), std::string::npos) << missing;
}

TEST_F(Hdf5Test, IntegerAttributesOfOtherWidthsReadAsInt64) {
  h5::File f = h5::File::create(file("w.h5"));
  const hid_t space = H5Screate(H5S_SCALAR);
  const hid_t attr = H5Acreate2(f.id(), "u8", H5T_STD_U8LE, space, H5P_DEFAULT, H5P_DEFAULT);
  const std::uint8_t value = 200;
  H5Awrite(attr, H5T_NATIVE_UINT8, &value);
  H5Aclose(attr);
  H5Sclose(space);
  EXPECT_EQ(f.attribute<std::int64_t>("u8"), 200);
}

// ---- groups -----------------------------------------------------------------------------------

TEST_F(Hdf5Test, GroupsNestListAndExist) {
  h5::File f = h5::File::create(file("g.h5"));
  h5::Group c = f.create_group("a/b/c");
  EXPECT_EQ(c.path(), "/a/b/c");
  f.create_group("a/zeta");
  f.open_group("a").write_dataset("data", Dims{1}, std::vector<std::uint8_t>{7});
  EXPECT_TRUE(f.exists("a/b/c"));
  EXPECT_TRUE(f.exists("/a/b"));
  EXPECT_FALSE(f.exists("a/x/y"));
  EXPECT_FALSE(f.exists("nothing"));
  EXPECT_EQ(f.open_group("a").children(), (std::vector<std::string>{"b", "data", "zeta"}));
  EXPECT_EQ(f.require_group("a/b").path(), "/a/b");
  EXPECT_EQ(f.require_group("new/one").path(), "/new/one");
  EXPECT_THROW(f.create_group("a/b"), LibraryError);
}

TEST_F(Hdf5Test, MissingObjectErrorNamesFilePathOperationAndCause) {
  const fs::path path = file("g.h5");
  h5::File f = h5::File::create(path);
  const std::string msg = message_of<LibraryError>([&] { (void)f.open_group("missing"); });
  EXPECT_EQ(msg.rfind(path.string() + ":/missing: cannot open group: ", 0), 0u) << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  EXPECT_GT(msg.size(), (path.string() + ":/missing: cannot open group: ").size() + 5) << msg;
}

// ---- files ------------------------------------------------------------------------------------

TEST_F(Hdf5Test, OpeningAMissingFileThrowsIoErrorNamingThePath) {
  const fs::path path = file("absent.h5");
  const std::string msg = message_of<IoError>([&] { (void)h5::File::open(path); });
  EXPECT_EQ(msg, path.string() + ": no such file");
}

TEST_F(Hdf5Test, OpeningANonHdf5FileThrowsIoErrorNamingThePath) {
  const fs::path path = file("x.h5");
  std::ofstream(path) << "this is not an HDF5 file\n";
  const std::string msg = message_of<IoError>([&] { (void)h5::File::open(path); });
  EXPECT_EQ(msg.rfind(path.string() + ": cannot open HDF5 file: ", 0), 0u) << msg;
  EXPECT_NE(msg.find("signature"), std::string::npos) << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
}

TEST_F(Hdf5Test, ExclusiveCreateOfAnExistingFileThrowsIoError) {
  const fs::path path = file("e.h5");
  { h5::File f = h5::File::create(path); }
  const std::string msg = message_of<IoError>([&] { (void)h5::File::create(path, h5::CreateMode::kExclusive); });
  EXPECT_EQ(msg.rfind(path.string() + ": cannot create HDF5 file", 0), 0u) << msg;
  EXPECT_NO_THROW((void)h5::File::create(path, h5::CreateMode::kTruncate));
}

TEST_F(Hdf5Test, CreatingInAMissingDirectoryThrowsIoError) {
  EXPECT_THROW((void)h5::File::create(file("no/such/dir/f.h5")), IoError);
}

TEST_F(Hdf5Test, ExplicitCloseReleasesTheFile) {
  const fs::path path = file("c.h5");
  h5::File f = h5::File::create(path);
  f.set_attribute("k", 1);
  f.flush();
  f.close();
  EXPECT_EQ(h5::File::open(path).attribute<std::int64_t>("k"), 1);
}

TEST_F(Hdf5Test, ReadOnlyFileRefusesWrites) {
  const fs::path path = file("ro.h5");
  { h5::File f = h5::File::create(path); }
  h5::File f = h5::File::open(path);
  EXPECT_THROW(f.set_attribute("k", 1), LibraryError);
}

TEST_F(Hdf5Test, NoIdentifierStaysOpenAfterScopesAndFailures) {
  {
    h5::File f = h5::File::create(file("l.h5"));
    h5::Group g = f.create_group("g");
    g.set_attribute("s", "x");
    g.write_strings("names", std::vector<std::string>{"a", "b"});
    (void)g.open_dataset("names").read_strings();
    (void)g.attribute<std::string>("s");
    (void)g.attribute_names();
    EXPECT_THROW((void)g.attribute<double>("s"), FormatError);
    EXPECT_THROW((void)g.create_dataset("d", h5::DataType::of<float>(), Dims{2, 2}, {.chunk = {3, 3}}), InvalidInput);
    EXPECT_THROW(g.write_strings("names", std::vector<std::string>{"dup"}), LibraryError);
    EXPECT_GT(H5Fget_obj_count(static_cast<hid_t>(H5F_OBJ_ALL), H5F_OBJ_ALL), 0);
  }
  EXPECT_EQ(H5Fget_obj_count(static_cast<hid_t>(H5F_OBJ_ALL), H5F_OBJ_ALL), 0);
}

TEST_F(Hdf5Test, FailuresPrintNoHdf5Diagnostics) {
  const fs::path text = file("x.h5");
  std::ofstream(text) << "not hdf5";
  {  // control: with automatic printing on, the capture does see HDF5-DIAG
    h5::silence_errors();
    StderrCapture capture(file("control.txt"));
    H5Eset_auto2(H5E_DEFAULT, print_stack, stderr);
    H5Fopen(text.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    ASSERT_NE(capture.finish().find("HDF5-DIAG"), std::string::npos) << "stderr capture does not work";
  }
  StderrCapture capture(file("stderr.txt"));
  EXPECT_THROW((void)h5::File::open(text), IoError);
  {
    h5::File f = h5::File::create(file("ok.h5"));
    EXPECT_THROW((void)f.open_dataset("missing"), LibraryError);
    EXPECT_THROW((void)f.create_group("g").create_group("/g"), LibraryError);
    f.set_attribute("s", "text");
    EXPECT_THROW((void)f.attribute<double>("s"), FormatError);
    h5::Dataset ds = f.write_dataset("d", Dims{2}, std::vector<float>{1, 2});
    EXPECT_THROW(ds.extend(4), LibraryError);
  }
  const std::string err = capture.finish();
  EXPECT_EQ(err.find("HDF5-DIAG"), std::string::npos) << err;
}

}  // namespace
