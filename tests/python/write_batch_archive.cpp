// write_batch_archive OUT.h5: writes shards (io/batch_shard.h) with known contents next to OUT.h5 and
// merges them into the batch archive OUT.h5 (io/batch_archive.h), for check_batch_archive.py, which reads
// it with h5py and with examples/load_archive.py. The shards are removed afterwards.
//
// Contents:
//   /batch/gim_9        3 items of shape (3, 9, 9), shards given in index order 2, 0, 1:
//                       index 0 "chair/a" label "chair", 1 "table/b" label "table", 2 "chair/c" label "chair";
//                       value index * 1000 + 0.5 * flat position; metrics psnr = 60 + index for all,
//                       hausdorff_rms = 0.125 only for index 1; no mask.
//                       failed: index 3 "table/d", reason "bad mesh: not manifold", 2 attempts.
//                       attributes method = "gim", size = "9".
//   /batch/sphere_octa_2  2 items of shape (3, 5, 5): index 0 "chair/a" with a mask whose sample 12 is 0,
//                       index 1 "table/b" without a mask (stored as all ones); value -index - 0.25 * position;
//                       no label for index 1 (""), metric seconds_total = 1.5; frame origins (metrics
//                       frame_origin_x/y/z) (4e5, 5e6, 250.5) for index 0 and (-1e7, 0.125, 0) for index 1;
//                       no failures.
//                       attributes method = "sphere", domain = "octa", n = "2".
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include "io/batch_archive.h"
#include "io/batch_shard.h"

namespace {

using namespace gimforge;
namespace fs = std::filesystem;

io::ItemArrays item(std::uint32_t side, double scale, double offset) {
  io::ItemArrays a{.channels = 3, .height = side, .width = side, .data = {}, .mask = {}, .metrics = {}, .sample_uv = {}};
  for (std::size_t i = 0; i < 3u * side * side; ++i)
    a.data.push_back(static_cast<float>(offset + scale * static_cast<double>(i)));
  return a;
}

io::MergeInput gim_output(const fs::path& dir) {
  io::MergeInput in{.output = "gim_9", .shards = {}, .failed = {}, .attributes = {{"method", "gim"}, {"size", "9"}}};
  const char* names[] = {"chair/a", "table/b", "chair/c"};
  const char* labels[] = {"chair", "table", "chair"};
  for (const std::uint64_t index : {2u, 0u, 1u}) {
    const io::ItemKey key{.output = in.output,
                          .name = names[index],
                          .source = std::string("meshes/") + names[index] + ".ply",
                          .label = labels[index],
                          .index = index};
    io::ItemArrays a = item(9, 0.5, 1000.0 * static_cast<double>(index));
    a.metrics["psnr"] = 60.0 + static_cast<double>(index);
    if (index == 1) a.metrics["hausdorff_rms"] = 0.125;
    const fs::path path = dir / in.output / (std::to_string(index) + ".h5");
    io::write_shard(path, key, a);
    in.shards.push_back(path);
  }
  in.failed.push_back({.key = {.output = in.output,
                               .name = "table/d",
                               .source = "meshes/table/d.ply",
                               .label = "table",
                               .index = 3},
                       .reason = "bad mesh: not manifold",
                       .attempts = 2});
  return in;
}

io::MergeInput sphere_output(const fs::path& dir) {
  io::MergeInput in{.output = "sphere_octa_2",
                    .shards = {},
                    .failed = {},
                    .attributes = {{"method", "sphere"}, {"domain", "octa"}, {"n", "2"}}};
  const char* names[] = {"chair/a", "table/b"};
  for (const std::uint64_t index : {0u, 1u}) {
    const io::ItemKey key{.output = in.output,
                          .name = names[index],
                          .source = std::string("meshes/") + names[index] + ".ply",
                          .label = index == 0 ? "chair" : "",
                          .index = index};
    io::ItemArrays a = item(5, -0.25, -static_cast<double>(index));
    a.metrics["seconds_total"] = 1.5;
    a.metrics["frame_origin_x"] = index == 0 ? 4e5 : -1e7;
    a.metrics["frame_origin_y"] = index == 0 ? 5e6 : 0.125;
    a.metrics["frame_origin_z"] = index == 0 ? 250.5 : 0.0;
    if (index == 0) {
      a.mask.assign(25, 1);
      a.mask[12] = 0;
    }
    const fs::path path = dir / in.output / (std::to_string(index) + ".h5");
    io::write_shard(path, key, a);
    in.shards.push_back(path);
  }
  return in;
}

void write_sample(const fs::path& out, const std::string& command_line) {
  fs::path shards = out;
  shards += ".shards";
  fs::remove_all(shards);
  const std::vector<io::MergeInput> outputs{gim_output(shards), sphere_output(shards)};
  io::write_batch_archive(out, {.creator = command_line, .parameters_json = R"({"batch": true})"}, outputs);
  fs::remove_all(shards);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: write_batch_archive OUT.h5\n");
    return 2;
  }
  try {
    write_sample(argv[1], std::string(argv[0]) + " " + argv[1]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "write_batch_archive: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
