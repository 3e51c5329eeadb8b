#pragma once
/// \file mpi.hpp
/// viscd across MPI ranks (component `mpi`, target viscd::mpi; docs/mpi.md): each rank passes
/// its own objects under global ids; the detector exchanges the objects near other ranks (ghosts)
/// and reports every overlapping pair exactly once over all ranks. Built where CMake finds MPI.

#include <mpi.h>

#include <compare>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "viscd/config.hpp"
#include "viscd/detector.hpp"
#include "viscd/frame.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd::mpi {

/// A pair of overlapping objects by their global ids, a < b.
struct GlobalPair {
  std::uint64_t a = 0, b = 0;
  friend constexpr auto operator<=>(const GlobalPair&, const GlobalPair&) = default;
};

/// One rank's objects for one frame (DistributedDetector::detect). Spans need only live for the
/// call. A frame holds spheres or boxes, and every rank must give the same kind (a rank with no
/// objects may give neither).
struct DistributedInput {
  std::span<const Sphere> spheres;
  std::span<const Box> boxes;
  /// One global id per object, unique over every rank's moving and static objects (checked
  /// whenever a rank's ids change). Pairs are reported in these ids.
  std::span<const std::uint64_t> ids;
  /// Empty, or one Filter per object (FrameInput::filters); ghosts carry their owner's filter.
  std::span<const Filter> filters;
  /// Empty, or one flag per object (FrameInput::always_active). Culling across ranks is not
  /// offered yet (docs/mpi.md), so every object is active and the flags change nothing; they are
  /// checked as FrameInput's are.
  std::span<const std::uint8_t> always_active;
};

/// What one rank did in one frame.
struct RankStats {
  std::uint32_t objects = 0;                 ///< this rank's moving objects
  std::uint32_t static_objects = 0;          ///< this rank's static objects
  std::uint32_t ghosts_received = 0;         ///< other ranks' moving objects near this rank's region
  std::uint32_t ghosts_sent = 0;             ///< copies of this rank's moving objects sent (one per rank they reach)
  std::uint32_t static_ghosts_received = 0;  ///< other ranks' static objects near this rank's moving objects
  std::uint32_t static_ghosts_sent = 0;      ///< copies of this rank's static objects sent
  std::uint64_t bytes_sent = 0;              ///< payload bytes this rank sent (regions, id checks, ghosts)
  std::uint64_t bytes_received = 0;          ///< payload bytes it received
  std::uint64_t pairs = 0;                   ///< pairs this rank reports (its share under the ownership rule)
  bool ids_checked = false;                  ///< the global ids were checked for repeats this frame
  double exchange_ms = 0;                    ///< checks, region, id check, ghost selection and exchange, wall
  double communication_ms = 0;               ///< of exchange_ms, the MPI calls that move data (waits included)
  double detect_ms = 0;                      ///< the local detector's frame over own + ghost objects, wall
  double total_ms = 0;                       ///< the whole detect() call, wall
};

/// One rank's result of one frame. Reuse it across frames: its buffers keep their capacity.
struct DistributedResult {
  /// This rank's share of the frame's pairs, by global id, a < b, sorted, unique. Over all ranks
  /// every overlapping pair appears exactly once (docs/mpi.md, "Who reports a pair"): a pair of two
  /// moving objects on the rank that owns the one with the smaller id, a pair of a moving and a
  /// static object on the rank that owns the moving one. Two static objects never pair.
  std::vector<GlobalPair> pairs;
  /// State of each of this rank's moving objects, in input order: colliding when it overlaps any
  /// object on any rank (pairs another rank reports count too).
  std::vector<ObjectState> state;
  RankStats stats;
  /// The local detector's frame over own + ghost objects (objects = own + ghosts).
  FrameStats local;
};

/// The first failing rank's status on every rank: a collective over `comm` (every rank calls it
/// with its own status; the lowest rank that failed wins). Its message starts with "rank R: ".
/// Returns ok on every rank when none failed. Also for callers that want their own input checks
/// to fail every rank alike (`viscd pairs` under mpirun does).
[[nodiscard]] Status agree(MPI_Comm comm, const Status& local);

/// A detector spread over the ranks of an MPI communicator. Every call marked collective must be
/// made by every rank of the communicator, in the same order. MPI must be initialized (MPI_Init or
/// MPI_Init_thread) before the detector is made and finalized only after it is destroyed; the
/// detector calls MPI only from the thread that calls it, on a communicator of its own (a
/// duplicate of `comm`, with errors returned rather than aborting), so any thread level works as
/// long as the caller does not call MPI from another thread at the same time.
///
/// Each rank owns its objects and a region, the box around them. A frame gathers every rank's
/// region, sends each rank copies (ghosts) of the objects that overlap its region, runs a local
/// detector (the cpu backend unless one is given) over own + ghost objects and keeps the pairs
/// this rank reports under the ownership rule. The result is exact: a rank's own objects overlap
/// nothing the frame does not see. Ranks may own regions that overlap; the price is more ghosts.
/// Culling is off: no camera is taken (docs/mpi.md, "Limits").
class DistributedDetector {
 public:
  /// Collective (MPI_Comm_dup). The local detector is the cpu backend with `config`.
  explicit DistributedDetector(MPI_Comm comm, const Config& config = {});
  /// Collective. Runs `local` (any backend; not null) over own + ghost objects.
  DistributedDetector(MPI_Comm comm, std::unique_ptr<Detector> local);
  ~DistributedDetector();
  DistributedDetector(const DistributedDetector&) = delete;
  DistributedDetector& operator=(const DistributedDetector&) = delete;

  /// Collective: one frame over every rank's objects. A failure on any rank (invalid shapes,
  /// ids that repeat on one or across ranks, spans of the wrong size, spheres on one rank and
  /// boxes on another, memory, the local detector's pair cap, an MPI error) fails the frame on
  /// every rank with the same kind and message ("rank R: ..."), and leaves `out` unspecified.
  [[nodiscard]] Status detect(const DistributedInput& input, DistributedResult& out);

  /// This rank's static objects (terrain, walls; Detector's static set), each with a global id
  /// (ids shared with the moving objects' id space) and an optional Filter. They replace the
  /// rank's previous static set and take effect at the next detect(); the kind must be that of
  /// the frames. Static objects are sent to the ranks whose moving objects they come near. Local:
  /// checks the shapes, the sizes and repeats within the rank (repeats across ranks are found by
  /// the next detect()).
  [[nodiscard]] Status set_static_spheres(std::span<const Sphere> spheres, std::span<const std::uint64_t> ids,
                                          std::span<const Filter> filters = {});
  [[nodiscard]] Status set_static_boxes(std::span<const Box> boxes, std::span<const std::uint64_t> ids,
                                        std::span<const Filter> filters = {});
  /// Empties this rank's static set (from the next detect()).
  void clear_static();

  /// Collective: every rank's pairs of `result` (this rank's last frame) gathered into `all` on
  /// `root`, sorted and unique: the frame's pairs, as one process would find them. `all` is
  /// cleared on every rank and filled on root only.
  [[nodiscard]] Status gather_pairs(const DistributedResult& result, std::vector<GlobalPair>& all, int root = 0);

  /// This rank and the number of ranks in the detector's communicator.
  [[nodiscard]] int rank() const;
  [[nodiscard]] int size() const;
  /// The local detector (its name, config, memory).
  [[nodiscard]] const Detector& local() const;

  struct State;  // defined in src/mpi/

 private:
  std::unique_ptr<State> state_;
};

}  // namespace viscd::mpi
