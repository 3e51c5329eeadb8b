#pragma once
// The frame pipeline every CPU-side detector shares: visibility (1) or the caller's id map,
// count (2), cull + mu + m (3), the collision filters' pre-pass, broadphase (4-8, backend
// specific), object states, shading (9). Detector::detect() has checked the input before.

#include <memory>
#include <span>
#include <vector>

#include "core/backend.hpp"
#include "core/frame_rules.hpp"
#include "core/with_static.hpp"
#include "cpu/parallel.hpp"
#include "cpu/visibility.hpp"

namespace viscd::detail {

class PipelineDetector : public Backend {
 public:
  [[nodiscard]] std::uint64_t memory_bytes() const final;
  /// The last frame's visibility map (empty without camera, or with the caller's id map); for
  /// tests and tools.
  [[nodiscard]] const VisibilityMap& visibility_map() const { return map_; }

 protected:
  explicit PipelineDetector(const Config& config) : Backend(config) {}
  /// The frame's thread count: Config::threads, 0 meaning the caller's executor's concurrency (or
  /// the hardware's). Call it inside an ExecutorScope of config_.executor.
  [[nodiscard]] int frame_threads() const {
    return resolve_threads(config_.threads, config_.executor ? config_.executor->concurrency() : 0);
  }
  [[nodiscard]] Status run_frame(const FrameInput& input, FrameResult& out) final;
  /// The objects checked in ranges on the frame's threads (a pass over every shape each frame).
  [[nodiscard]] Status validate_objects(const Shapes& objects) final;
  /// On the frame's threads.
  void for_chunks_of(std::size_t n, const std::function<void(std::size_t, std::size_t)>& f) final;
  /// Stage 1 into map_ (already sized): every object, the static ones after the moving ones. Only
  /// a backend that draws on a device can fail (the cpu rasterizers return ok).
  [[nodiscard]] virtual Status rasterize(const CameraRig& cam, const Shapes& objects, int threads) = 0;
  /// Stage 1 of a frame: the frame's objects and the static set's into map_ (ids: moving k as
  /// k + 1, the static set's live objects after them in slot order). By default rasterize() over
  /// both at once; a backend may keep the static objects' layer between frames.
  [[nodiscard]] virtual Status draw_frame(const CameraRig& cam, const Camera& camera, const FrameInput& in,
                                          int threads);
  /// Bytes held by the backend's own stages (raster, broadphase).
  [[nodiscard]] virtual std::uint64_t backend_memory_bytes() const = 0;
  /// Stages 4-8 over `pairable` (ascending: the active objects that can pair with another under
  /// the filters, all active objects without filters); `filters` is empty or one per object and
  /// decides each candidate pair. Objects from `static_from` on are the static set's: no pair of
  /// two of them is reported. Writes sorted pairs (of object indices; run_frame() reports the
  /// static ones) and stats (bits, layout, stage times). `unpaired` (ascending) are the active
  /// objects left out of `pairable`: they pair with nothing but queries see them.
  [[nodiscard]] virtual Status broadphase(const Shapes& objects, std::span<const std::uint32_t> pairable,
                                          std::span<const std::uint32_t> unpaired, std::span<const Filter> filters,
                                          std::uint32_t static_from, int bits, int threads, std::vector<Pair>& pairs,
                                          FrameStats& stats) = 0;

  /// Stages 4-8 by following change (cpu: Config::follow_change, cpu/rest_set.hpp), before the
  /// filters' pre-pass: sets `done` when it wrote the frame's pairs (filters and the active set
  /// applied, static pairs as static_index(slot), sorted) and stats; else the frame runs
  /// broadphase(). `active` ascending, the moving objects only (handles_static()).
  [[nodiscard]] virtual Status follow_change(const FrameInput& in, const Shapes& objects,
                                             std::span<const std::uint32_t> active, std::span<const Filter> filters,
                                             int bits, int threads, std::vector<Pair>& pairs, FrameStats& stats,
                                             bool& done) {
    (void)in, (void)objects, (void)active, (void)filters, (void)bits, (void)threads, (void)pairs, (void)stats;
    done = false;
    return {};
  }
  /// After a frame that follow_change() did: the objects in its pairs, one bit each (moving
  /// objects only), when it knows them without a pass over the pairs; else null.
  [[nodiscard]] virtual const std::uint64_t* followed_pair_bits() const { return nullptr; }
  /// The last frame's active objects, ascending (the static set's after them unless handles_static()).
  [[nodiscard]] std::span<const std::uint32_t> last_active() const { return active_; }

  /// Whether the backend keeps the static set in a structure of its own (cpu): then broadphase()
  /// gets the moving objects only and adds their pairs with the static set itself (reported as
  /// static_index(slot), the pairs sorted). Otherwise the static objects are appended to the
  /// frame's (WithStatic).
  [[nodiscard]] virtual bool handles_static() const { return false; }

  VisibilityMap map_;
  WithStatic all_;   // what the broadphase gets: the frame's objects, with the static set's unless handles_static()
  WithStatic draw_;  // what the map shows: the frame's objects and the static set's

 private:
  std::vector<std::uint32_t> counts_, hist_, active_, pairable_, unpaired_;
  std::vector<std::uint64_t> in_pair_;  // the states' pass: objects in pairs, a bitset per chunk
  CountScratch count_scratch_;
  CullScratch cull_scratch_;
};

/// The filters' pre-pass: with G the OR of the groups and M the OR of the masks over `active`, an
/// object can pair with another only when (mask & G) != 0 and (group & M) != 0. Splits `active`
/// (ascending) into those that can and the rest, both ascending, written to the front of
/// `pairable` and `unpaired` (grown to filters.size() when shorter, never shrunk).
struct FilterSplit {
  std::span<const std::uint32_t> pairable, unpaired;
};
/// `groups` and `masks` start the ORs (the static set's, when it is not among `active`).
FilterSplit split_by_filters(std::span<const std::uint32_t> active, std::span<const Filter> filters,
                             std::vector<std::uint32_t>& pairable, std::vector<std::uint32_t>& unpaired,
                             std::uint32_t groups = 0, std::uint32_t masks = 0);

}  // namespace viscd::detail
