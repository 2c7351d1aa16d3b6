// The batch run (jobs/batch_run.h) in one process over the serial communicator: every method goes through
// the one pipeline and stores what `convert` stores; relief maps keep one group per item, identical to the
// group `convert` writes; a stop request leaves a resumable job whose resume gives the same archive.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "io/archive.h"
#include "io/batch_archive.h"
#include "io/batch_shard.h"
#include "io/input_file.h"
#include "io/relief_archive.h"
#include "jobs/batch_item.h"
#include "jobs/batch_run.h"
#include "jobs/load_mesh.h"
#include "jobs/pipeline.h"
#include "mpi/comm.h"
#include "tests/unit/test_support.h"

namespace gimforge::jobs {
namespace {

namespace fs = std::filesystem;

const std::string kData = GIMFORGE_TEST_DATA_DIR;

class BatchRunTest : public test::ScratchDirTest {
 protected:
  void SetUp() override {
    ScratchDirTest::SetUp();
    fs::create_directories(dir_ / "in/round");
    fs::create_directories(dir_ / "in/boxy");
    // Small closed genus-0 meshes: every method converts them in well under a second (also under ASan).
    fs::copy_file(kData + "/tetra.obj", dir_ / "in/round/tetra.obj");
    fs::copy_file(kData + "/cube.off", dir_ / "in/boxy/cube.off");
  }

  [[nodiscard]] BatchOptions options(Method method, const std::string& archive) const {
    BatchOptions o;
    o.input = (dir_ / "in").string();
    o.output = file(archive).string();
    o.method.method = method;
    o.method.size = 65;
    o.method.n = 8;
    o.method.grid = "4";
    o.method.texture = 8;
    o.metric_samples = 5000;
    o.max_retries = 0;
    o.progress = false;
    return o;
  }

  /// What a fresh gim run stores: its output's name, the items' identities and the stacked data.
  struct Fresh {
    std::string out;
    std::vector<io::ItemKey> keys;
    std::vector<float> data;
  };
  [[nodiscard]] Fresh fresh_gim_run() const {
    const BatchOptions fresh = options(Method::Gim, "fresh.h5");
    EXPECT_EQ(run_batch(mpi::Comm::serial(), fresh).status, BatchStatus::Done);
    Fresh f{fresh.method.default_output_name(), {}, {}};
    const io::Archive a = io::Archive::open(fresh.output);
    const h5::Group g = a.root().open_group("batch/" + f.out);
    const std::vector<std::string> names = g.open_dataset("names").read_strings();
    const std::vector<std::string> sources = g.open_dataset("sources").read_strings();
    const std::vector<std::string> labels = g.open_dataset("labels").read_strings();
    for (std::size_t i = 0; i < names.size(); ++i) f.keys.push_back({f.out, names[i], sources[i], labels[i], i});
    f.data = g.open_dataset("data").read<float>();
    return f;
  }

  /// An interrupted gim job (nothing converted) whose journal says item `key` is done in `shard` (relative to
  /// the work folder), written with other data (all 42) under `key`'s identity at `written`.
  [[nodiscard]] BatchOptions forged_done_item(const io::ItemKey& key, const std::string& shard,
                                              const fs::path& written) const {
    BatchOptions o = options(Method::Gim, "gim.h5");
    EXPECT_EQ(run_batch(mpi::Comm::serial(), o, [] { return true; }).status, BatchStatus::Stopped);
    const std::uint32_t side = o.method.size;
    const io::ItemArrays forged{.channels = 3, .height = side, .width = side,
                                .data = std::vector<float>(3u * side * side, 42.0f), .mask = {}, .metrics = {},
                                .sample_uv = {}};
    fs::create_directories(written.parent_path());
    io::write_shard(written, key, forged);
    std::ofstream journal(o.output + ".work/journal.jsonl", std::ios::app);
    journal << nlohmann::json{{"event", "done"}, {"output", key.output}, {"name", key.name}, {"index", key.index},
                              {"shard", shard}}.dump()
            << "\n";
    o.resume = true;
    return o;
  }
};

/// Names of the numbers a convert of `mesh` with `method` records (values vary: timings).
std::set<std::string> convert_numbers(const MethodOptions& method, const std::string& mesh, std::size_t samples) {
  const LoadedMesh m = load_mesh(mesh, load_policy(method.method, false));
  ConversionRequest request;
  request.method = method;
  request.method.normal_size = 0;
  request.fidelity.samples = samples;
  const EmbreeDevice device;
  std::set<std::string> keys;
  for (const auto& entry : convert_mesh(device, m.mesh, request).numbers) keys.insert(entry.first);
  return keys;
}

TEST_F(BatchRunTest, EveryMethodStoresTheStatisticsConvertRecords) {
  for (const Method method : kMethods) {
    const std::string archive = std::string(method_name(method)) + ".h5";
    const BatchOptions o = options(method, archive);
    const BatchOutcome outcome = run_batch(mpi::Comm::serial(), o);
    ASSERT_EQ(outcome.status, BatchStatus::Done) << method_name(method);
    EXPECT_EQ(outcome.converted, 2u);
    const auto summary = io::read_batch_summary(file(archive));
    ASSERT_EQ(summary.size(), 1u);
    EXPECT_EQ(summary[0].output, o.method.default_output_name());
    EXPECT_EQ(summary[0].count, 2u);
    EXPECT_EQ(summary[0].groups, method == Method::Relief || method == Method::Mcgim) << method_name(method);
    EXPECT_EQ(summary[0].attributes.at("method"), method_name(method));
    std::set<std::string> expected = convert_numbers(o.method, kData + "/tetra.obj", o.metric_samples);
    expected.insert("input_faces");
    const std::set<std::string> stored(summary[0].metric_keys.begin(), summary[0].metric_keys.end());
    EXPECT_EQ(stored, expected) << method_name(method);
    EXPECT_TRUE(stored.contains("psnr") && stored.contains("seconds_construct") && stored.contains("seconds_metric"));
  }
}

/// Whether two datasets of a relief group hold the same values.
bool same_values(const h5::Dataset& a, const h5::Dataset& b) {
  switch (a.dtype()) {
    case h5::DType::kUInt8: return a.read<std::uint8_t>() == b.read<std::uint8_t>();
    case h5::DType::kInt8: return a.read<std::int8_t>() == b.read<std::int8_t>();
    case h5::DType::kUInt16: return a.read<std::uint16_t>() == b.read<std::uint16_t>();
    case h5::DType::kUInt32: return a.read<std::uint32_t>() == b.read<std::uint32_t>();
    case h5::DType::kInt64: return a.read<std::int64_t>() == b.read<std::int64_t>();
    case h5::DType::kFloat64: return a.read<double>() == b.read<double>();
    default: ADD_FAILURE() << "unexpected element type in a relief group"; return false;
  }
}

TEST_F(BatchRunTest, ReliefItemsAreTheGroupsConvertWrites) {
  const BatchOptions o = options(Method::Relief, "relief.h5");
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::Done);
  // Items are stored by path: in/boxy/cube.off is item 0, in/round/tetra.obj item 1.
  const io::Archive batch = io::Archive::open(file("relief.h5"));
  const h5::Group item = batch.root().open_group("batch/" + o.method.default_output_name() + "/items/1");

  const LoadedMesh m = load_mesh(kData + "/tetra.obj", load_policy(Method::Relief, false));
  ConversionRequest request;
  request.method = o.method;
  request.fidelity.samples = o.metric_samples;
  const EmbreeDevice device;
  const Conversion c = convert_mesh(device, m.mesh, request);
  {
    io::Archive single = io::Archive::create(file("single.h5"), {});
    write_conversion(single, "tetra", c);
    single.close();
  }
  const io::Archive single = io::Archive::open(file("single.h5"));
  const h5::Group group = single.root().open_group("relief/tetra");
  ASSERT_EQ(item.children(), group.children());
  for (const std::string& name : group.children()) {
    const h5::Dataset a = item.open_dataset(name), b = group.open_dataset(name);
    EXPECT_EQ(a.shape(), b.shape()) << name;
    EXPECT_EQ(a.dtype(), b.dtype()) << name;
    EXPECT_TRUE(same_values(a, b)) << name;
  }
  for (const char* key : {"n", "texture", "grey_cells", "layers"})
    EXPECT_EQ(item.attribute<std::int64_t>(key), group.attribute<std::int64_t>(key)) << key;
  EXPECT_EQ(item.attribute<double>("psnr"), group.attribute<double>("psnr"));
}

TEST_F(BatchRunTest, StopRequestLeavesAResumableJobThatFinishesTheSame) {
  BatchOptions o = options(Method::Gim, "gim.h5");
  const BatchOutcome stopped = run_batch(mpi::Comm::serial(), o, [] { return true; });
  EXPECT_EQ(stopped.status, BatchStatus::Stopped);
  EXPECT_FALSE(fs::exists(o.output));
  EXPECT_TRUE(fs::exists(o.output + ".work/journal.jsonl"));
  // Without --resume the interrupted job is refused; with it, it finishes.
  EXPECT_NE(test::message_of<InvalidInput>([&] { (void)run_batch(mpi::Comm::serial(), o); }).find("--resume"),
            std::string::npos);
  o.resume = true;
  const BatchOutcome done = run_batch(mpi::Comm::serial(), o);
  EXPECT_EQ(done.status, BatchStatus::Done);
  EXPECT_EQ(done.converted, 2u);
  EXPECT_FALSE(fs::exists(o.output + ".work"));

  BatchOptions fresh = options(Method::Gim, "gim_fresh.h5");
  ASSERT_EQ(run_batch(mpi::Comm::serial(), fresh).status, BatchStatus::Done);
  const io::Archive a = io::Archive::open(o.output), b = io::Archive::open(fresh.output);
  const std::string data = "batch/" + o.method.default_output_name() + "/data";
  EXPECT_EQ(a.root().open_dataset(data).read<float>(), b.root().open_dataset(data).read<float>());
}

TEST_F(BatchRunTest, ResumeUsesOnlyTheShardPathItsItemHas) {
  // The journal claims item 0 is done in a shard outside its work directory: a valid shard of the right
  // item, with other data.
  const Fresh fresh = fresh_gim_run();
  const BatchOptions o = forged_done_item(fresh.keys[0], "../outside.h5", file("outside.h5"));
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::Done);
  const io::Archive resumed = io::Archive::open(o.output);
  EXPECT_EQ(resumed.root().open_dataset("batch/" + fresh.out + "/data").read<float>(), fresh.data)
      << "the item was redone, not taken from the journal's foreign path";
}

TEST_F(BatchRunTest, LinksInTheWorkDirectoryAreNeverFollowed) {
  // A committed shard that is a link to a valid shard elsewhere is redone; a link in place of the output's
  // shard folder is removed, not written through (the resume wrote every new shard into the folder it named).
  const Fresh fresh = fresh_gim_run();
  const std::string shard = "shards/" + fresh.out + "/0.h5";
  const BatchOptions o = forged_done_item(fresh.keys[0], shard, file("outside.h5"));
  fs::create_symlink(file("outside.h5"), file("gim.h5.work") / shard);
  fs::create_directories(file("elsewhere"));
  fs::rename(file("gim.h5.work/shards") / fresh.out, file("elsewhere/moved"));
  fs::create_symlink(file("elsewhere"), file("gim.h5.work/shards") / fresh.out);
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::Done);
  const io::Archive resumed = io::Archive::open(o.output);
  EXPECT_EQ(resumed.root().open_dataset("batch/" + fresh.out + "/data").read<float>(), fresh.data);
  EXPECT_EQ(std::distance(fs::directory_iterator(file("elsewhere")), fs::directory_iterator()), 1)
      << "nothing written through the link";
}

TEST_F(BatchRunTest, ResumeTakesTheCollectionSpelledAnotherWayAndNamesWhatChanged) {
  BatchOptions o = options(Method::Gim, "gim.h5");
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o, [] { return true; }).status, BatchStatus::Stopped);
  o.resume = true;
  const auto refused = [&](BatchOptions changed) {
    return test::message_of<InvalidInput>([&] { (void)run_batch(mpi::Comm::serial(), changed); });
  };
  BatchOptions relabelled = o;
  relabelled.label = "none";  // the journal's labels were silently kept
  EXPECT_NE(refused(relabelled).find("--resume with a different job: item 0 ('"), std::string::npos) << refused(relabelled);
  EXPECT_NE(refused(relabelled).find("was labelled 'boxy', now ''"), std::string::npos) << refused(relabelled);
  BatchOptions larger = o;
  larger.method.size = 129;
  // Named as the journal holds it: the new options name the output differently.
  EXPECT_NE(refused(larger).find("output 'gim_65' (now 'gim_129'): size was 65, now 129"), std::string::npos)
      << refused(larger);
  EXPECT_FALSE(fs::exists(file("gim.h5.work/shards/gim_129"))) << "a refused resume leaves nothing of its own";
  fs::copy_file(kData + "/tetra.obj", dir_ / "in/round/tetra2.obj");
  EXPECT_NE(refused(o).find("the collection had 2 items, now 3"), std::string::npos) << refused(o);
  fs::remove(dir_ / "in/round/tetra2.obj");
  // The same folder by another path: the same job.
  o.input = (dir_ / "in" / "." / ".." / "in").string();
  EXPECT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::Done);
}

TEST_F(BatchRunTest, ResumeRedoesAnItemWhoseSourceChangedSince) {
  // Item 0 was committed (other data, stamped with its source as it was then); the source is rewritten
  // before the resume (here: a new modification time).
  const Fresh fresh = fresh_gim_run();
  io::ItemKey key = fresh.keys[0];
  key.source_stamp = io::file_stamp(key.source);
  const std::string shard = "shards/" + fresh.out + "/0.h5";
  const BatchOptions o = forged_done_item(key, shard, file("gim.h5.work") / shard);
  fs::last_write_time(key.source, fs::last_write_time(key.source) + std::chrono::seconds(5));
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::Done);
  const io::Archive resumed = io::Archive::open(o.output);
  EXPECT_EQ(resumed.root().open_dataset("batch/" + fresh.out + "/data").read<float>(), fresh.data)
      << "the item was converted again from its changed source";
}

TEST_F(BatchRunTest, AResumedArchiveRecordsEverySourceAsItsRunSpellsIt) {
  // Item 0 was committed by a run that spelled the collection one way; the resume spells it another (a job
  // resumed from another directory: relative sources of the first run named files relative to that one).
  // The archive mixed both spellings in `sources`.
  const Fresh fresh = fresh_gim_run();
  const std::string shard = "shards/" + fresh.out + "/0.h5";
  BatchOptions o = forged_done_item(fresh.keys[0], shard, file("gim.h5.work") / shard);
  o.input = (dir_ / "in" / "." / ".." / "in").string();
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::Done);
  const io::Archive resumed = io::Archive::open(o.output);
  const auto sources = resumed.root().open_dataset("batch/" + fresh.out + "/sources").read_strings();
  ASSERT_EQ(sources.size(), 2u);
  for (const std::string& source : sources) EXPECT_TRUE(source.starts_with(o.input)) << source;
  EXPECT_EQ(resumed.root().open_dataset("batch/" + fresh.out + "/data").read<float>()[0], 42.0f) << "the shard was kept";
}

TEST_F(BatchRunTest, ResumeRetriesAFailedItemWhoseSourceWasRewrittenSince) {
  // Item 0 failed "not retried" (the journal's record, stamped with its source as it was then). A resume keeps
  // that failure while the source is unchanged, and converts the item again once the source was rewritten:
  // the failure once outlived the fix, which a clean run would have converted.
  const auto journal_failure = [&](const BatchOptions& o, const std::string& stamp) {
    const io::ItemKey key = fresh_gim_run().keys[0];
    std::ofstream journal(o.output + ".work/journal.jsonl", std::ios::app);
    journal << nlohmann::json{{"event", "failed"}, {"output", key.output}, {"name", key.name}, {"index", 0},
                              {"attempt", 1}, {"reason", "broken" + std::string(kNotRetried)}, {"stamp", stamp}}.dump()
            << "\n";
    return key.source;
  };
  for (const bool rewritten : {false, true}) {
    SCOPED_TRACE(rewritten);
    BatchOptions o = options(Method::Gim, rewritten ? "rewritten.h5" : "same.h5");
    ASSERT_EQ(run_batch(mpi::Comm::serial(), o, [] { return true; }).status, BatchStatus::Stopped);
    const std::string source = journal_failure(o, io::file_stamp((dir_ / "in/boxy/cube.off").string()));
    ASSERT_EQ(fs::path(source).filename(), "cube.off");
    if (rewritten) fs::last_write_time(source, fs::last_write_time(source) + std::chrono::seconds(5));
    o.resume = true;
    const BatchOutcome resumed = run_batch(mpi::Comm::serial(), o);
    EXPECT_EQ(resumed.status, rewritten ? BatchStatus::Done : BatchStatus::Partial);
    EXPECT_EQ(resumed.converted, rewritten ? 2u : 1u);
    fs::remove_all(file("fresh.h5"));
  }
  // The record a failed attempt leaves carries its source's stamp (attempts that time out, stopped before
  // their retry).
  BatchOptions o = options(Method::Gim, "timeout.h5");
  o.item_timeout = 1e-6;
  o.max_retries = 1;
  const std::string journal = o.output + ".work/journal.jsonl";
  const auto journal_text = [&] {
    std::ostringstream text;
    text << std::ifstream(journal).rdbuf();
    return text.str();
  };
  const auto failed_once = [&] { return journal_text().find(R"("event":"failed")") != std::string::npos; };
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o, failed_once).status, BatchStatus::Stopped);
  const std::string text = journal_text();
  const auto stamped = [&](const char* source) {
    return text.find(R"("stamp":")" + io::file_stamp((dir_ / "in" / source).string()) + "\"") != std::string::npos;
  };
  EXPECT_TRUE(stamped("boxy/cube.off") || stamped("round/tetra.obj")) << text;
}

// An earlier gimforge labelled a --list item by the line's last directory part ("" for "a.ply" and ".." for
// "../a.ply" in a list in the current folder); this one by the folder holding it. A batch it started still
// resumes, with its labels; any other change of a label is refused (it was silently kept).
TEST_F(BatchRunTest, AJobStartedWithTheEarlierListLabelsStillResumes) {
  const fs::path cwd = fs::current_path();
  struct Back {
    fs::path to;
    ~Back() { fs::current_path(to); }
  } back{cwd};
  fs::current_path(dir_ / "in/round");
  fs::copy_file(kData + "/cube.off", dir_ / "in/cube.off");
  BatchOptions o = options(Method::Gim, "gim.h5");
  o.input.clear();
  o.list = "list.txt";
  std::ofstream(o.list) << "tetra.obj\n../cube.off\n";
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o, [] { return true; }).status, BatchStatus::Stopped);
  const fs::path journal = o.output + ".work/journal.jsonl";
  const auto forge = [&](const std::map<std::string, std::string>& labels) {  // by source
    std::ifstream in(journal);
    std::string first, rest, line;
    std::getline(in, first);
    while (std::getline(in, line)) rest += line + "\n";
    nlohmann::json start = nlohmann::json::parse(first);
    EXPECT_EQ(start["job"]["items"].size(), labels.size());
    for (nlohmann::json& item : start["job"]["items"]) item[2] = labels.at(item[1].get<std::string>());
    in.close();
    std::ofstream(journal, std::ios::trunc) << start.dump() << "\n" << rest;
  };
  o.resume = true;
  forge({{"tetra.obj", ""}, {"../cube.off", "x"}});  // not a label the earlier rule gave ../cube.off
  const std::string refused = test::message_of<InvalidInput>([&] { (void)run_batch(mpi::Comm::serial(), o); });
  EXPECT_NE(refused.find("('../cube.off') was labelled 'x', now 'in'"), std::string::npos) << refused;
  forge({{"tetra.obj", ""}, {"../cube.off", ".."}});  // the earlier rule's labels
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::Done);
  const io::Archive a = io::Archive::open(o.output);
  std::vector<std::string> labels = a.root().open_dataset("batch/" + o.method.default_output_name() + "/labels").read_strings();
  std::sort(labels.begin(), labels.end());
  EXPECT_EQ(labels, (std::vector<std::string>{"", ".."}));
  // Its finished archive is still its own: --resume again finds it complete.
  EXPECT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::AlreadyComplete);
}

TEST_F(BatchRunTest, ADamagedJournalSaysHowToStartOver) {
  BatchOptions o = options(Method::Gim, "gim.h5");
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o, [] { return true; }).status, BatchStatus::Stopped);
  std::ofstream(o.output + ".work/journal.jsonl", std::ios::app) << "garbage\n";
  o.resume = true;
  const std::string m = test::message_of<InvalidInput>([&] { (void)run_batch(mpi::Comm::serial(), o); });
  EXPECT_NE(m.find("journal.jsonl:2: invalid journal record"), std::string::npos) << m;
  EXPECT_NE(m.find("remove " + o.output + ".work to start over"), std::string::npos) << m;
}

TEST_F(BatchRunTest, AJournalWithoutItsJobRecordIsDamagedNotAnotherJobsWork) {
  // Item 0 done, then the journal's first record (the job) lost: the done record could be any job's (a probe
  // resumed such a journal with other options and got their items mixed, exit 0).
  const Fresh fresh = fresh_gim_run();
  const std::string shard = "shards/" + fresh.out + "/0.h5";
  const BatchOptions o = forged_done_item(fresh.keys[0], shard, file("gim.h5.work") / shard);
  const fs::path journal = o.output + ".work/journal.jsonl";
  std::vector<std::string> lines;
  for (std::ifstream in(journal); std::getline(in, lines.emplace_back());) {}
  ASSERT_GE(lines.size(), 2u);
  ASSERT_NE(lines.front().find("\"job\""), std::string::npos) << lines.front();
  std::ofstream out(journal, std::ios::trunc);
  for (std::size_t i = 1; i < lines.size(); ++i)
    if (!lines[i].empty()) out << lines[i] << "\n";
  out.close();
  const std::string m = test::message_of<InvalidInput>([&] { (void)run_batch(mpi::Comm::serial(), o); });
  EXPECT_NE(m.find("records of items but none of their job (the journal is damaged: remove"), std::string::npos) << m;
}

TEST_F(BatchRunTest, NoMetricStoresNoFidelity) {
  BatchOptions o = options(Method::Relief, "quiet.h5");
  o.no_metric = true;
  ASSERT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::Done);
  const auto summary = io::read_batch_summary(file("quiet.h5"));
  ASSERT_EQ(summary.size(), 1u);
  const std::set<std::string> stored(summary[0].metric_keys.begin(), summary[0].metric_keys.end());
  for (const char* key : {"psnr", "hausdorff_rms", "hausdorff_max", "bbox_diagonal"}) EXPECT_FALSE(stored.contains(key)) << key;
  EXPECT_TRUE(stored.contains("storage_bytes") && stored.contains("seconds_construct"));
}

TEST_F(BatchRunTest, DamagedReliefShardIsRefused) {
  const LoadedMesh m = load_mesh(kData + "/tetra.obj", load_policy(Method::Relief, false));
  ConversionRequest request;
  request.method = options(Method::Relief, "unused.h5").method;
  request.fidelity.enabled = false;
  const EmbreeDevice device;
  const Conversion c = convert_mesh(device, m.mesh, request);
  const BatchItem item = batch_item(c);
  const io::ItemKey key{"relief_4_8", "tetra", "tetra.obj", "", 0};
  io::write_shard(file("good.h5"), key, item.arrays, item.representation);
  EXPECT_TRUE(io::read_shard_info(file("good.h5")).has_representation);
  // The same shard without its distance maps: a damaged shard (a resumed batch redoes it).
  io::write_shard(file("bad.h5"), key, item.arrays, [&](h5::Group& g) {
    item.representation(g);
    H5Ldelete(g.id(), "distances", H5P_DEFAULT);
  });
  const std::string msg = test::message_of<FormatError>([&] { (void)io::read_shard_info(file("bad.h5")); });
  EXPECT_NE(msg.find("no dataset 'distances'"), std::string::npos) << msg;
  EXPECT_NE(msg.find(file("bad.h5").string()), std::string::npos) << msg;
}

TEST_F(BatchRunTest, MethodOptionsAreCheckedBeforeAnyWork) {
  BatchOptions o = options(Method::Relief, "bad.h5");
  o.method.texture = 1;
  EXPECT_NE(test::message_of<InvalidInput>([&] { (void)run_batch(mpi::Comm::serial(), o); }).find("texture"),
            std::string::npos);
  EXPECT_FALSE(fs::exists(o.output + ".work"));
}

TEST_F(BatchRunTest, AFolderThatIsNotABatchsWorkFolderIsLeftAlone) {
  // A batch removes ARCHIVE.work when it ends: a user's folder of that name (here the collection itself), a
  // link, or one holding anything but a batch's journal, shards and bricks is refused before any work.
  BatchOptions o = options(Method::Gim, "coll");
  fs::rename(dir_ / "in", dir_ / "coll.work");
  o.input = (dir_ / "coll.work").string();
  EXPECT_NE(test::message_of<InvalidInput>([&] { (void)run_batch(mpi::Comm::serial(), o); })
                .find("is not a gimforge work folder"),
            std::string::npos);
  EXPECT_TRUE(fs::exists(dir_ / "coll.work/round/tetra.obj"));
  fs::rename(dir_ / "coll.work", dir_ / "in");
  o.input = (dir_ / "in").string();
  fs::create_directories(dir_ / "notes");
  std::ofstream(dir_ / "notes/keep.txt") << "precious";
  fs::create_directory_symlink(dir_ / "notes", dir_ / "coll.work");
  EXPECT_NE(test::message_of<InvalidInput>([&] { (void)run_batch(mpi::Comm::serial(), o); }).find("symbolic link"),
            std::string::npos);
  fs::remove(dir_ / "coll.work");
  fs::create_directories(dir_ / "coll.work");  // a journal that is a link: appends would go where it points
  fs::create_symlink(dir_ / "notes/keep.txt", dir_ / "coll.work/journal.jsonl");
  EXPECT_NE(test::message_of<InvalidInput>([&] { (void)run_batch(mpi::Comm::serial(), o); }).find("journal.jsonl"),
            std::string::npos);
  fs::remove(dir_ / "coll.work/journal.jsonl");
  fs::create_directories(dir_ / "coll.work/shards");  // what a run killed before its journal leaves: ours
  EXPECT_EQ(run_batch(mpi::Comm::serial(), o).status, BatchStatus::Done);
  EXPECT_FALSE(fs::exists(dir_ / "coll.work"));
  EXPECT_TRUE(fs::exists(dir_ / "notes/keep.txt"));
  EXPECT_EQ(fs::directory_iterator(dir_ / "notes")->path().filename(), "keep.txt");
}

}  // namespace
}  // namespace gimforge::jobs
