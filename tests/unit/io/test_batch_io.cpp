// Tests of the batch I/O: the journal (io/journal.h), shards (io/batch_shard.h) and the consolidated
// batch archive (io/batch_archive.h), including damaged files and failures in the middle of a merge.
#include <gtest/gtest.h>

#include "tests/unit/test_support.h"
#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/archive.h"
#include "io/atomic_file.h"
#include "io/batch_archive.h"
#include "io/batch_shard.h"
#include "io/journal.h"
#include "kernels/core/errors.h"

namespace fs = std::filesystem;
using namespace gimforge;
using gimforge::test::message_of;
using nlohmann::json;

namespace {

class BatchIoTest : public gimforge::test::ScratchDirTest {
 protected:
  /// Writes shard `name` for `key`/`arrays` into the scratch directory and returns its path.
  fs::path shard(const io::ItemKey& key, const io::ItemArrays& arrays) {
    const fs::path path = file("shards") / key.output / (std::to_string(key.index) + ".h5");
    io::write_shard(path, key, arrays);
    return path;
  }
};

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
}

/// True when `dir` holds a file whose name ends with ".tmp".
bool has_tmp_file(const fs::path& dir) {
  for (const auto& entry : fs::recursive_directory_iterator(dir))
    if (entry.path().extension() == ".tmp") return true;
  return false;
}

io::ItemKey key_of(std::uint64_t index, const std::string& label = "chair", const std::string& output = "gim_9") {
  return {.output = output,
          .name = (label.empty() ? "item" : label) + "/" + std::to_string(index),
          .source = "meshes/" + label + "/" + std::to_string(index) + ".ply",
          .label = label,
          .index = index};
}

/// An item of shape (C, H, W) whose value at flat position i is index * 1000 + i; with a mask whose
/// sample k is 0 when k % 3 == 0.
io::ItemArrays arrays_of(std::uint64_t index, std::uint32_t c = 3, std::uint32_t h = 4, std::uint32_t w = 5,
                         bool with_mask = false) {
  io::ItemArrays a{.channels = c, .height = h, .width = w, .data = {}, .mask = {}, .metrics = {}, .sample_uv = {}};
  for (std::size_t i = 0; i < std::size_t{c} * h * w; ++i)
    a.data.push_back(static_cast<float>(index * 1000 + i));
  if (with_mask)
    for (std::size_t k = 0; k < std::size_t{h} * w; ++k) a.mask.push_back(k % 3 == 0 ? 0 : 1);
  a.metrics = {{"psnr", 60.0 + static_cast<double>(index)}, {"seconds_total", 0.5}};
  return a;
}

/// Overwrites the bytes of chunk (0, ...) of dataset `name` in `path` with 0xFF, so the metadata stays
/// readable but the compressed data cannot be decoded.
void damage_first_chunk(const fs::path& path, const std::string& name) {
  haddr_t address = 0;
  hsize_t size = 0;
  {
    const h5::File f = h5::File::open(path);
    const h5::Dataset ds = f.open_dataset(name);
    const std::vector<hsize_t> origin(ds.shape().size(), 0);
    unsigned filter_mask = 0;
    ASSERT_GE(H5Dget_chunk_info_by_coord(ds.id(), origin.data(), &filter_mask, &address, &size), 0);
  }
  ASSERT_GT(size, 0u);
  std::fstream io(path, std::ios::binary | std::ios::in | std::ios::out);
  io.seekp(static_cast<std::streamoff>(address));
  const std::string garbage(static_cast<std::size_t>(size), '\xFF');
  io.write(garbage.data(), static_cast<std::streamsize>(garbage.size()));
}

// ---- journal ----------------------------------------------------------------------------------

TEST_F(BatchIoTest, JournalAppendThenReplayKeepsRecordsInOrder) {
  const fs::path path = file("run/journal.jsonl");
  fs::create_directories(path.parent_path());
  const std::vector<json> records = {
      {{"event", "start"}, {"job", {{"outputs", {"gim_65"}}, {"max_retries", 2}}}},
      {{"event", "done"}, {"output", "gim_65"}, {"name", "a"}, {"index", 0}, {"shard", "shards/gim_65/0.h5"}},
      {{"event", "failed"}, {"output", "gim_65"}, {"name", "b"}, {"index", 1}, {"attempt", 1}, {"reason", "x ü"}}};
  {
    io::Journal journal = io::Journal::open(path);
    for (const json& r : records) journal.append(r);
  }
  std::size_t torn = 7;
  EXPECT_EQ(io::Journal::replay(path, &torn), records);
  EXPECT_EQ(torn, 0u);
  const std::string text = read_text(path);
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 3);

  {  // reopening appends, it does not truncate
    io::Journal journal = io::Journal::open(path);
    journal.append({{"event", "note"}});
  }
  EXPECT_EQ(io::Journal::replay(path).size(), 4u);
}

TEST_F(BatchIoTest, JournalIgnoresATornLastLineAndOpenCutsItOff) {
  const fs::path path = file("journal.jsonl");
  const std::string complete = R"({"event":"done","output":"o","name":"a","index":0,"shard":"s0.h5"})"
                               "\n";
  for (const std::string& torn_tail : {std::string(R"({"event":"done","outp)"),
                                       std::string(R"({"event":"note"})")}) {  // complete JSON, no newline yet
    write_text(path, complete + torn_tail);
    std::size_t torn = 0;
    EXPECT_EQ(io::Journal::replay(path, &torn).size(), 1u) << torn_tail;
    EXPECT_EQ(torn, 1u);
    {
      io::Journal journal = io::Journal::open(path);
      journal.append({{"event", "note"}, {"n", 2}});
    }
    EXPECT_EQ(read_text(path), complete + "{\"event\":\"note\",\"n\":2}\n");
    EXPECT_EQ(io::Journal::replay(path, &torn).size(), 2u);
    EXPECT_EQ(torn, 0u);
  }
}

TEST_F(BatchIoTest, JournalRejectsGarbageInTheMiddleNamingTheLine) {
  const fs::path path = file("journal.jsonl");
  write_text(path, "{\"event\":\"a\"}\n\n{\"event\":\"b\"} trailing\n{\"event\":\"c\"}\n");
  std::string msg = message_of<FormatError>([&] { (void)io::Journal::replay(path); });
  EXPECT_NE(msg.find(path.string() + ":3: invalid journal record: not valid JSON"), std::string::npos) << msg;

  write_text(path, "{\"event\":\"a\"}\n[1, 2]\n{\"event\":\"c\"}\n");
  msg = message_of<FormatError>([&] { (void)io::Journal::replay(path); });
  EXPECT_NE(msg.find(path.string() + ":2: invalid journal record: a JSON array, expected an object"),
            std::string::npos)
      << msg;
}

TEST_F(BatchIoTest, JournalErrors) {
  const fs::path path = file("journal.jsonl");
  std::string msg = message_of<IoError>([&] { (void)io::Journal::replay(path); });
  EXPECT_EQ(msg, path.string() + ": no such journal");

  io::Journal journal = io::Journal::open(path);
  msg = message_of<InvalidInput>([&] { journal.append(json::array({1, 2})); });
  EXPECT_NE(msg.find("must be a JSON object, got array"), std::string::npos) << msg;

  msg = message_of<IoError>([&] { (void)io::Journal::open(file("missing_dir/journal.jsonl")); });
  EXPECT_NE(msg.find("missing_dir/journal.jsonl: cannot open journal: No such file"), std::string::npos) << msg;
}

TEST_F(BatchIoTest, JournalReplacesInvalidUtf8InsteadOfFailing) {
  const fs::path path = file("journal.jsonl");
  {
    io::Journal journal = io::Journal::open(path);
    journal.append({{"event", "failed"}, {"reason", std::string("bad \xFF byte")}});
  }
  const auto records = io::Journal::replay(path);
  ASSERT_EQ(records.size(), 1u);
  EXPECT_EQ(records[0]["reason"], "bad \xEF\xBF\xBD byte");
}

TEST(JournalSummary, FoldsStartDoneAndFailedRecords) {
  const std::vector<json> records = {
      {{"event", "start"}, {"job", {{"run", 1}}}},
      {{"event", "failed"}, {"output", "o"}, {"name", "b"}, {"index", 1}, {"attempt", 1}, {"reason", "timeout"}},
      {{"event", "done"}, {"output", "o"}, {"name", "a"}, {"index", 0}, {"shard", "s/0.h5"}},
      {{"event", "start"}, {"job", {{"run", 2}}}},
      {{"event", "failed"}, {"output", "o"}, {"name", "b"}, {"index", 1}, {"attempt", 2}, {"reason", "bad mesh"}},
      {{"event", "done"}, {"output", "o"}, {"name", "a"}, {"index", 0}, {"shard", "s/0-redo.h5"}},
      {{"event", "done"}, {"output", "p"}, {"name", "a"}, {"index", 0}, {"shard", "t/0.h5"}},
      {{"something", "else"}}};
  const io::JournalState state = io::summarize(records);
  EXPECT_EQ(state.starts, 2u);
  ASSERT_TRUE(state.job.has_value());
  EXPECT_EQ((*state.job)["run"], 2);
  const io::JournalKey a{"o", 0}, b{"o", 1}, pa{"p", 0};
  EXPECT_EQ(state.done, (std::map<io::JournalKey, std::string>{{a, "s/0-redo.h5"}, {pa, "t/0.h5"}}));
  EXPECT_EQ(state.failures, (std::map<io::JournalKey, std::vector<std::string>>{{b, {"timeout", "bad mesh"}}}));
  EXPECT_EQ(state.names.at(b), "b");
}

TEST(JournalSummary, OnlyTheAttemptsAtTheSourceAsLastStampedCount) {
  // Two attempts at the source as it was, a rewrite, one attempt at the new file: a second --resume counted
  // all three (batch_run forgets them only when the file changed since the last record).
  const auto failed = [](const char* reason, const char* stamp) {
    json r = {{"event", "failed"}, {"output", "o"}, {"name", "a"}, {"index", 0}, {"reason", reason}};
    if (stamp != nullptr) r["stamp"] = stamp;
    return r;
  };
  const io::JournalKey a{"o", 0};
  io::JournalState state = io::summarize({failed("r1", "10:1"), failed("r2", "10:1"), failed("r3", "12:2")});
  EXPECT_EQ(state.failures.at(a), std::vector<std::string>{"r3"});
  EXPECT_EQ(state.failure_stamps.at(a), "12:2");
  // A record of an earlier gimforge (no stamp): the attempts count, and the source they saw is unknown.
  state = io::summarize({failed("r1", nullptr), failed("r2", "10:1"), failed("r3", nullptr)});
  EXPECT_EQ(state.failures.at(a), (std::vector<std::string>{"r1", "r2", "r3"}));
  EXPECT_FALSE(state.failure_stamps.contains(a));
}

TEST(JournalSummary, RejectsMalformedRecordsNamingThem) {
  const auto msg_for = [](const json& bad) {
    return message_of<FormatError>([&] { (void)io::summarize({{{"event", "start"}, {"job", {}}}, bad}); });
  };
  EXPECT_EQ(msg_for({{"event", "done"}, {"output", "o"}, {"name", "a"}, {"index", 0}}),
            "journal record 2 (done): missing 'shard'");
  EXPECT_EQ(msg_for({{"event", "done"}, {"output", "o"}, {"name", "a"}, {"index", -1}, {"shard", "s"}}),
            "journal record 2 (done): 'index' is not a non-negative integer");
  EXPECT_EQ(msg_for({{"event", "failed"}, {"output", 3}, {"name", "a"}, {"index", 0}, {"reason", "r"}}),
            "journal record 2 (failed): 'output' is not a string");
}

// ---- shards -----------------------------------------------------------------------------------

TEST_F(BatchIoTest, ShardRoundTripsWithAndWithoutMask) {
  for (const bool with_mask : {false, true}) {
    const io::ItemKey key = key_of(42, "lamp");
    const io::ItemArrays arrays = arrays_of(42, 3, 4, 5, with_mask);
    const fs::path path = shard(key, arrays);
    EXPECT_FALSE(has_tmp_file(file("shards")));

    const io::Shard back = io::read_shard(path);
    EXPECT_EQ(back.key.output, key.output);
    EXPECT_EQ(back.key.name, key.name);
    EXPECT_EQ(back.key.source, key.source);
    EXPECT_EQ(back.key.label, key.label);
    EXPECT_EQ(back.key.index, 42u);
    EXPECT_EQ(back.arrays.channels, 3u);
    EXPECT_EQ(back.arrays.height, 4u);
    EXPECT_EQ(back.arrays.width, 5u);
    EXPECT_EQ(back.arrays.data, arrays.data);
    EXPECT_EQ(back.arrays.mask, arrays.mask);
    EXPECT_EQ(back.arrays.metrics, arrays.metrics);

    const io::ShardInfo info = io::read_shard_info(path);
    EXPECT_EQ(info.has_mask, with_mask);
    EXPECT_EQ(info.metrics, arrays.metrics);
  }
}

TEST_F(BatchIoTest, WriteShardReplacesAnExistingShard) {
  const io::ItemKey key = key_of(1);
  const fs::path path = shard(key, arrays_of(1));
  io::write_shard(path, key, arrays_of(7));
  EXPECT_EQ(io::read_shard(path).arrays.data, arrays_of(7).data);
}

TEST_F(BatchIoTest, WriteShardRefusesInconsistentItems) {
  const io::ItemKey key = key_of(3);
  io::ItemArrays a = arrays_of(3);
  a.data.pop_back();
  EXPECT_EQ(message_of<InvalidInput>([&] { io::write_shard(file("x.h5"), key, a); }),
            "item 'chair/3' (output 'gim_9', index 3): 59 data values for shape (3, 4, 5)");
  a = arrays_of(3, 3, 4, 5, true);
  a.mask[4] = 2;
  EXPECT_EQ(message_of<InvalidInput>([&] { io::write_shard(file("x.h5"), key, a); }),
            "item 'chair/3' (output 'gim_9', index 3): mask value 2 at 4 (expected 0 or 1)");
  a = arrays_of(3);
  a.metrics["bad/name"] = 1.0;
  std::string msg = message_of<InvalidInput>([&] { io::write_shard(file("x.h5"), key, a); });
  EXPECT_NE(msg.find("invalid metric name 'bad/name'"), std::string::npos) << msg;
  msg = message_of<InvalidInput>([&] { io::write_shard(file("x.h5"), key_of(3, "c", "a/b"), arrays_of(3)); });
  EXPECT_NE(msg.find("invalid batch output name 'a/b'"), std::string::npos) << msg;
  EXPECT_FALSE(fs::exists(file("x.h5")));
  EXPECT_FALSE(has_tmp_file(dir_));
}

TEST_F(BatchIoTest, FailedShardCommitLeavesNoTemporaryFile) {
  const fs::path path = file("occupied");
  fs::create_directories(path / "inside");  // rename(2) cannot replace a non-empty directory
  const std::string msg = message_of<IoError>([&] { io::write_shard(path, key_of(0), arrays_of(0)); });
  EXPECT_NE(msg.find(path.string() + ": cannot commit:"), std::string::npos) << msg;
  EXPECT_FALSE(fs::exists(io::temporary_path(path)));
  EXPECT_TRUE(fs::is_directory(path / "inside"));
}

TEST_F(BatchIoTest, TemporaryNamesArePerProcessAndLeftoversCanBeRemoved) {
  const fs::path path = file("shards/o/1.h5");
  const fs::path tmp = io::temporary_path(path);
  EXPECT_EQ(tmp.parent_path(), path.parent_path());
  EXPECT_TRUE(tmp.filename().string().starts_with("1.h5."));
  EXPECT_NE(tmp.filename().string().find(std::to_string(getpid())), std::string::npos) << tmp;
  EXPECT_EQ(tmp.extension(), ".tmp");

  fs::create_directories(path.parent_path());
  write_text(tmp, "partial");
  write_text(file("shards/2.h5.other-host.77.tmp"), "partial");
  write_text(file("shards/o/3.h5"), "kept");
  EXPECT_EQ(io::remove_temporary_files(file("shards")), 2u);
  EXPECT_FALSE(has_tmp_file(file("shards")));
  EXPECT_TRUE(fs::exists(file("shards/o/3.h5")));
  EXPECT_EQ(io::remove_temporary_files(file("absent")), 0u);
}

TEST_F(BatchIoTest, DamagedShardsAreFormatErrorsNamingTheShard) {
  const fs::path good = shard(key_of(5), arrays_of(5, 3, 16, 16));
  const std::string bytes = read_text(good);

  const fs::path missing = file("missing.h5");
  EXPECT_EQ(message_of<FormatError>([&] { (void)io::read_shard(missing); }),
            missing.string() + ": batch shard is missing");

  const fs::path truncated = file("truncated.h5");
  write_text(truncated, bytes.substr(0, bytes.size() / 2));
  std::string msg = message_of<FormatError>([&] { (void)io::read_shard(truncated); });
  EXPECT_TRUE(msg.starts_with(truncated.string() + ": unreadable batch shard: ")) << msg;

  const fs::path random = file("random.h5");
  std::mt19937 rng(7);
  std::string noise(4096, '\0');
  for (char& c : noise) c = static_cast<char>(rng() & 0xFF);
  write_text(random, noise);
  msg = message_of<FormatError>([&] { (void)io::read_shard_info(random); });
  EXPECT_TRUE(msg.starts_with(random.string() + ": unreadable batch shard: ")) << msg;

  const fs::path archive = file("archive.h5");
  io::Archive::create(archive, {}).close();
  EXPECT_EQ(message_of<FormatError>([&] { (void)io::read_shard(archive); }),
            archive.string() + ": unreadable batch shard: not a batch shard (format is 'gimforge')");

  damage_first_chunk(good, "data");
  EXPECT_NO_THROW((void)io::read_shard_info(good));  // the metadata is intact
  msg = message_of<FormatError>([&] { (void)io::read_shard(good); });
  EXPECT_TRUE(msg.starts_with(good.string() + ": unreadable batch shard: ")) << msg;
  EXPECT_NE(msg.find("data"), std::string::npos) << msg;
}

// ---- merge ------------------------------------------------------------------------------------

io::CreationInfo merge_info() { return {.creator = "gimforge batch test", .parameters_json = R"({"batch":true})"}; }

class BatchMergeTest : public BatchIoTest {
 protected:
  /// Writes the shards of items `indices` (label "" for multiples of 5, else "chair" for even and
  /// "table" for odd indices) and returns their paths in the same order.
  std::vector<fs::path> make_shards(const std::vector<std::uint64_t>& indices) {
    std::vector<fs::path> paths;
    for (const std::uint64_t i : indices)
      paths.push_back(shard(key_of(i, i % 5 == 0 ? "" : (i % 2 == 0 ? "chair" : "table")), arrays_of(i)));
    return paths;
  }
};

TEST_F(BatchMergeTest, StoresItemsInIndexOrderWhateverTheShardOrder) {
  const std::vector<std::uint64_t> indices{7, 2, 9, 4, 5};
  const std::vector<fs::path> shards = make_shards(indices);
  std::vector<fs::path> reversed(shards.rbegin(), shards.rend());
  const fs::path a = file("a.h5"), b = file("b.h5");
  io::write_batch_archive(a, merge_info(), std::vector{io::MergeInput{.output = "gim_9", .shards = shards}});
  io::write_batch_archive(b, merge_info(), std::vector{io::MergeInput{.output = "gim_9", .shards = reversed}});
  EXPECT_FALSE(has_tmp_file(dir_));

  const h5::File fa = h5::File::open(a), fb = h5::File::open(b);
  const h5::Dataset data = fa.open_dataset("batch/gim_9/data");
  ASSERT_EQ(data.shape(), (h5::Dims{5, 3, 4, 5}));
  const std::vector<std::uint64_t> sorted{2, 4, 5, 7, 9};
  for (std::uint64_t row = 0; row < sorted.size(); ++row)
    EXPECT_EQ(data.read_slab<float>({row, 0, 0, 0}, {1, 3, 4, 5}), arrays_of(sorted[row]).data) << row;
  EXPECT_EQ(data.read<float>(), fb.open_dataset("batch/gim_9/data").read<float>());
  EXPECT_EQ(fa.open_dataset("batch/gim_9/index").read<std::int64_t>(), (std::vector<std::int64_t>{2, 4, 5, 7, 9}));
  EXPECT_EQ(fa.open_dataset("batch/gim_9/names").read_strings(),
            (std::vector<std::string>{"chair/2", "chair/4", "item/5", "table/7", "table/9"}));
  EXPECT_EQ(fa.open_dataset("batch/gim_9/sources").read_strings()[0], "meshes/chair/2.ply");
  EXPECT_EQ(fa.open_dataset("batch/gim_9/label_names").read_strings(), (std::vector<std::string>{"chair", "table"}));
  EXPECT_EQ(fa.open_dataset("batch/gim_9/label_index").read<std::int32_t>(),
            (std::vector<std::int32_t>{0, 0, -1, 1, 1}));
  EXPECT_FALSE(fa.exists("batch/gim_9/mask"));
  EXPECT_EQ(fa.open_group("batch/gim_9").attribute<std::int64_t>("count"), 5);
  EXPECT_EQ(io::Archive::open(a).info().creation_parameters, R"({"batch":true})");
}

TEST_F(BatchMergeTest, MetricsAreTheUnionWithNaNForMissingOnes) {
  io::ItemArrays first = arrays_of(0), second = arrays_of(1);
  first.metrics = {{"psnr", 70.0}};
  second.metrics = {{"hausdorff_rms", 0.25}, {"psnr", 65.0}};
  const std::vector<fs::path> shards{shard(key_of(0), first), shard(key_of(1), second)};
  const fs::path path = file("m.h5");
  io::write_batch_archive(path, merge_info(), std::vector{io::MergeInput{.output = "gim_9", .shards = shards}});
  const h5::File f = h5::File::open(path);
  EXPECT_EQ(f.open_group("batch/gim_9/metrics").children(), (std::vector<std::string>{"hausdorff_rms", "psnr"}));
  EXPECT_EQ(f.open_dataset("batch/gim_9/metrics/psnr").read<double>(), (std::vector<double>{70.0, 65.0}));
  const auto rms = f.open_dataset("batch/gim_9/metrics/hausdorff_rms").read<double>();
  ASSERT_EQ(rms.size(), 2u);
  EXPECT_TRUE(std::isnan(rms[0]));
  EXPECT_EQ(rms[1], 0.25);
}

TEST_F(BatchMergeTest, MaskIsStackedWithAllOnesForItemsWithoutOne) {
  const std::vector<fs::path> shards{shard(key_of(0), arrays_of(0, 3, 4, 5, true)), shard(key_of(1), arrays_of(1))};
  const fs::path path = file("mask.h5");
  io::write_batch_archive(path, merge_info(), std::vector{io::MergeInput{.output = "gim_9", .shards = shards}});
  const h5::Dataset mask = h5::File::open(path).open_dataset("batch/gim_9/mask");
  ASSERT_EQ(mask.shape(), (h5::Dims{2, 1, 4, 5}));
  std::vector<std::uint8_t> expected = arrays_of(0, 3, 4, 5, true).mask;
  expected.resize(40, 1);
  EXPECT_EQ(mask.read<std::uint8_t>(), expected);
}

TEST_F(BatchMergeTest, WritesTheFailedTableAndAttributes) {
  const std::vector<fs::path> shards = make_shards({0, 2});
  const std::vector<io::FailedItem> failed{{key_of(3, "table"), "timeout after 60 s", 3},
                                           {key_of(1, "table"), "not manifold", 2}};
  const fs::path path = file("f.h5");
  io::write_batch_archive(path, merge_info(),
                          std::vector{io::MergeInput{.output = "gim_9",
                                                     .shards = shards,
                                                     .failed = failed,
                                                     .attributes = {{"method", "gim"}, {"size", "9"}}}});
  const h5::File f = h5::File::open(path);
  const h5::Group g = f.open_group("batch/gim_9");
  EXPECT_EQ(g.open_dataset("failed/names").read_strings(), (std::vector<std::string>{"table/1", "table/3"}));
  EXPECT_EQ(g.open_dataset("failed/reasons").read_strings(),
            (std::vector<std::string>{"not manifold", "timeout after 60 s"}));
  EXPECT_EQ(g.open_dataset("failed/attempts").read<std::int32_t>(), (std::vector<std::int32_t>{2, 3}));
  EXPECT_EQ(g.open_dataset("failed/index").read<std::int64_t>(), (std::vector<std::int64_t>{1, 3}));
  EXPECT_EQ(g.attribute<std::string>("method"), "gim");
  EXPECT_EQ(g.attribute<std::int64_t>("failed_count"), 2);

  const std::vector<io::BatchOutputSummary> summary = io::read_batch_summary(path);
  ASSERT_EQ(summary.size(), 1u);
  EXPECT_EQ(summary[0].output, "gim_9");
  EXPECT_EQ(summary[0].count, 2u);
  EXPECT_EQ(summary[0].item_shape, (h5::Dims{3, 4, 5}));
  EXPECT_EQ(summary[0].names, (std::vector<std::string>{"item/0", "chair/2"}));
  EXPECT_EQ(summary[0].indices, (std::vector<std::uint64_t>{0, 2}));
  EXPECT_EQ(summary[0].failed_names, (std::vector<std::string>{"table/1", "table/3"}));
  EXPECT_EQ(summary[0].metric_keys, (std::vector<std::string>{"psnr", "seconds_total"}));
  EXPECT_EQ(summary[0].attributes, (std::map<std::string, std::string>{{"method", "gim"}, {"size", "9"}}));
}

TEST_F(BatchMergeTest, AnOutputWithOnlyFailuresHasAnEmptyStack) {
  const fs::path path = file("empty.h5");
  io::write_batch_archive(path, merge_info(),
                          std::vector{io::MergeInput{.output = "gim_9", .failed = {{key_of(0), "bad mesh", 1}}}});
  const auto summary = io::read_batch_summary(path);
  ASSERT_EQ(summary.size(), 1u);
  EXPECT_EQ(summary[0].count, 0u);
  EXPECT_TRUE(summary[0].item_shape.empty());
  EXPECT_EQ(summary[0].failed_names, (std::vector<std::string>{"chair/0"}));
}

TEST_F(BatchMergeTest, RefusesDuplicatesShapeMismatchesAndForeignItems) {
  const fs::path path = file("never.h5");
  const auto refuse = [&](std::vector<io::MergeInput> inputs) {
    return message_of<InvalidInput>([&] { io::write_batch_archive(path, merge_info(), inputs); });
  };
  const std::vector<fs::path> shards = make_shards({0, 1});
  const fs::path copy = file("copy_of_1.h5");
  fs::copy_file(shards[1], copy);

  std::string msg = refuse({{.output = "gim_9", .shards = {shards[1], shards[0], copy}}});
  EXPECT_NE(msg.find("batch output 'gim_9': index 1 occurs twice: item 'table/1' (index 1, shard "),
            std::string::npos)
      << msg;
  msg = refuse({{.output = "gim_9", .shards = shards, .failed = {{key_of(1, "x"), "late failure", 1}}}});
  EXPECT_NE(msg.find("index 1 occurs twice"), std::string::npos) << msg;
  io::FailedItem renamed{key_of(8, "table"), "r", 1};
  renamed.key.name = "table/1";
  msg = refuse({{.output = "gim_9", .shards = shards, .failed = {renamed}}});
  EXPECT_NE(msg.find("name 'table/1' occurs twice"), std::string::npos) << msg;

  const fs::path odd = shard(key_of(4, "chair"), arrays_of(4, 3, 8, 5));
  msg = refuse({{.output = "gim_9", .shards = {odd, shards[0], shards[1]}}});
  EXPECT_NE(msg.find("batch output 'gim_9': item 'chair/4' (index 4, shard " + odd.string() +
                     ") has shape (3, 8, 5), item 'item/0' has (3, 4, 5)"),
            std::string::npos)
      << msg;

  const fs::path foreign = shard(key_of(6, "chair", "gim_17"), arrays_of(6));
  msg = refuse({{.output = "gim_9", .shards = {shards[0], foreign}}});
  EXPECT_NE(msg.find("item 'chair/6' (index 6, shard " + foreign.string() + ") belongs to output 'gim_17'"),
            std::string::npos)
      << msg;

  msg = refuse({{.output = "gim_9", .shards = shards, .attributes = {{"count", "3"}}}});
  EXPECT_EQ(msg, "batch output 'gim_9': attribute 'count' is reserved for the merge");
  msg = refuse({{.output = "gim_9", .shards = shards}, {.output = "gim_9"}});
  EXPECT_EQ(msg, "batch output 'gim_9': given twice");
  msg = refuse({{.output = "..", .shards = {}}});
  EXPECT_NE(msg.find("invalid batch output name '..'"), std::string::npos) << msg;

  EXPECT_FALSE(fs::exists(path));
  EXPECT_FALSE(fs::exists(io::temporary_path(path)));
}

TEST_F(BatchMergeTest, AFailureMidMergeLeavesNoFileAndKeepsAnOlderArchive) {
  const std::vector<fs::path> shards = make_shards({0, 1, 2});
  const fs::path path = file("archive.h5");
  const std::vector<io::MergeInput> inputs{{.output = "gim_9", .shards = shards}};

  damage_first_chunk(shards[2], "data");  // passes the metadata check, fails while streaming pixels
  std::string msg = message_of<FormatError>([&] { io::write_batch_archive(path, merge_info(), inputs); });
  EXPECT_TRUE(msg.starts_with(shards[2].string() + ": unreadable batch shard: ")) << msg;
  EXPECT_FALSE(fs::exists(path));
  EXPECT_FALSE(fs::exists(io::temporary_path(path)));

  // An archive already in place survives a failed merge untouched.
  io::write_batch_archive(path, merge_info(), std::vector<io::MergeInput>{{.output = "gim_9", .shards = {shards[0]}}});
  const std::string before = read_text(path);
  msg = message_of<FormatError>([&] { io::write_batch_archive(path, merge_info(), inputs); });
  EXPECT_EQ(read_text(path), before);
  EXPECT_FALSE(fs::exists(io::temporary_path(path)));
  EXPECT_EQ(io::read_batch_summary(path).at(0).count, 1u);

  // A shard deleted after the journal said it was committed is named, not skipped.
  fs::remove(shards[1]);
  msg = message_of<FormatError>([&] { io::write_batch_archive(path, merge_info(), inputs); });
  EXPECT_EQ(msg, shards[1].string() + ": batch shard is missing");
}

TEST_F(BatchMergeTest, AnOutputWithoutItsStackSaysSo) {
  const fs::path path = file("stackless.h5");
  io::write_batch_archive(path, merge_info(), std::vector<io::MergeInput>{{.output = "gim_9", .shards = make_shards({0, 1})}});
  {
    const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    ASSERT_GE(H5Ldelete(f, "batch/gim_9/data", H5P_DEFAULT), 0);
    H5Fclose(f);
  }
  const std::string msg = message_of<FormatError>([&] { (void)io::read_batch_summary(path); });
  EXPECT_NE(msg.find("batch output 'gim_9': holds neither dataset 'data' nor group 'items'"), std::string::npos) << msg;
}

TEST_F(BatchMergeTest, SummaryOfAnArchiveWithoutBatchOutputsIsAFormatError) {
  const fs::path path = file("plain.h5");
  io::Archive::create(path, {}).close();
  EXPECT_EQ(message_of<FormatError>([&] { (void)io::read_batch_summary(path); }),
            path.string() + ": no batch outputs (no /batch group)");
}

}  // namespace
