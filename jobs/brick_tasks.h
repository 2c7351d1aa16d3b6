#pragma once
/// \file brick_tasks.h
/// A huge scan in `batch` as brick tasks (issue #17 item 5): an item whose image goes through a proxy of
/// more than one brick (jobs/proxy_bricks.h) is not converted by one worker from start to end; it becomes
///   1. a **plan** task: one streaming pass over the file finds the loader's repairs (faces with a repeated
///      vertex, exact duplicate faces), the local frame, the proxy's target and the k-d bricks, and writes
///      them to a plan file (two bytes per vertex: its brick and its seam mark);
///   2. one **piece** task per brick: reads the brick's faces and decimates them with the seams locked,
///      writing the piece to a file;
///   3. a **finish** task: welds the pieces into the proxy (finish_pieces), then converts the item as a
///      whole-mesh item is converted — the method on the proxy, every sample moved onto the full surface,
///      the fidelity against it — and commits the item's shard.
/// The tasks join the batch's largest-first scheduler beside the whole-mesh items (mpi/scheduler.h
/// follow-ups), and each is journaled, so that --resume keeps the plan and the pieces already made. The
/// result is the one `convert` makes in one process, bit for bit: the same bricks, pieces and proxy.
///
/// Plan and piece files are the batch's own work files (in ARCHIVE.work/bricks/); they record the source
/// file's size, modification time and inode, and a source that changed since makes its plan stale
/// (kStaleBricks): the item is planned again.
#include <array>
#include <cstdint>
#include <filesystem>
#include <string_view>
#include <vector>

#include "io/ply_ranges.h"
#include "jobs/method.h"
#include "jobs/pipeline.h"

namespace gimforge::jobs {

/// In the message of a source changed since its plan.
inline constexpr std::string_view kStaleBricks = "changed since its bricks were planned";

/// A brick task found its plan or piece unusable: the source changed since the plan (kStaleBricks), or a work
/// file is missing, not a regular file, damaged (checksum), of an earlier plan or inconsistent with the scan.
/// Not the item's fault: the coordinator plans it again (a batch's work files are its own).
class StaleBricks : public IoError {
 public:
  using IoError::IoError;
};

/// How a worker reports StaleBricks to the master (the scheduler carries text): the failure reason starts
/// with this.
inline constexpr std::string_view kStaleBricksReason = "bricks to be planned again: ";

/// Whether `source` converted for `method` goes by brick tasks: an image method, a binary PLY of triangles
/// readable in pieces (io/ply_ranges.h) whose face count calls for a proxy (MethodOptions::proxy_target) of
/// more than one brick (MethodOptions::proxy_bricks, or proxy_bricks of the sizes). Never throws: a file that
/// cannot be read is converted whole, which reports why.
[[nodiscard]] bool converts_by_brick_tasks(const std::filesystem::path& source, const MethodOptions& method) noexcept;

/// What the master schedules after a plan: the faces of each brick (a brick without faces gets no task).
/// No bricks: after the repairs the scan needs no proxy of several bricks; it is converted whole.
struct BrickPlanSummary {
  std::vector<std::uint64_t> brick_faces;
  std::uint64_t nonce{0};     ///< the plan's random number, which its pieces repeat
  std::uint64_t vertices{0};  ///< the scan file's vertices
};

/// The files of one item's brick tasks, in its own directory `dir`: plan.bin and <brick>.bin.
[[nodiscard]] std::filesystem::path brick_plan_file(const std::filesystem::path& dir);
[[nodiscard]] std::filesystem::path brick_piece_file(const std::filesystem::path& dir, std::size_t brick);

/// The plan task: writes brick_plan_file(dir) (atomically) and returns its summary. Throws the reader's
/// errors (FormatError naming the file), InvalidInput "FILE: no faces with three distinct vertices".
BrickPlanSummary plan_brick_tasks(const std::filesystem::path& source, const MethodOptions& method,
                                  const std::filesystem::path& dir);

/// The summary of the plan in `dir` (--resume). Throws the source's read errors, and
/// StaleBricks when the plan is unusable or `source` changed since.
[[nodiscard]] BrickPlanSummary read_brick_plan(const std::filesystem::path& dir, const std::filesystem::path& source);

/// The piece task of brick `brick`: writes brick_piece_file(dir, brick) (atomically).
void decimate_brick_task(const std::filesystem::path& source, const std::filesystem::path& dir, std::size_t brick);

/// Checks that brick `brick`'s piece in `dir` reads back and was made from `plan` (--resume). Throws
/// StaleBricks.
void check_brick_piece(const std::filesystem::path& dir, std::size_t brick, const BrickPlanSummary& plan);

/// The finish task's proxy: the pieces in `dir` (one per brick with faces, in brick order) welded and
/// decimated to the target. Refuses (FormatError with kStaleBricks) a conversion whose frame, target or face
/// count is not the plan's.
[[nodiscard]] ProxyMaker proxy_from_pieces(const std::filesystem::path& source, const std::filesystem::path& dir);

/// Exact duplicate faces of `file` (the same three vertices in any order; the first in file order stays, as
/// the loader keeps it), ascending; faces with a repeated vertex are not counted. Streams the faces in as many
/// passes as keep at most `keys_per_pass` faces in memory at once (each pass takes the faces whose least
/// vertex falls in its residue class).
[[nodiscard]] std::vector<std::uint64_t> find_duplicate_faces(const io::PlyTriangleFile& file,
                                                              std::size_t keys_per_pass = std::size_t{1} << 24);

}  // namespace gimforge::jobs
