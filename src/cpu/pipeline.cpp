#include "cpu/pipeline.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cstring>
#include <limits>
#include <new>
#include <optional>

#include "core/frame_rules.hpp"
#include "core/morton.hpp"
#include "core/stopwatch.hpp"
#include "cpu/grow.hpp"
#include "cpu/pair_collector.hpp"
#include "cpu/parallel.hpp"

namespace viscd::detail {

std::uint64_t PipelineDetector::memory_bytes() const {
  return map_.memory_bytes() + all_.memory_bytes() + draw_.memory_bytes() + bytes_of(counts_) + bytes_of(hist_) +
         count_scratch_.memory_bytes() + cull_scratch_.memory_bytes() + bytes_of(active_) + bytes_of(pairable_) +
         bytes_of(in_pair_) + bytes_of(unpaired_) + backend_memory_bytes();
}

FilterSplit split_by_filters(std::span<const std::uint32_t> active, std::span<const Filter> filters,
                             std::vector<std::uint32_t>& pairable, std::vector<std::uint32_t>& unpaired,
                             std::uint32_t groups, std::uint32_t masks) {
  for (const std::uint32_t k : active) groups |= filters[k].group, masks |= filters[k].mask;
  // Sized once for every object and never shrunk: no allocation, and no clearing, per frame.
  if (pairable.size() < filters.size()) pairable.resize(filters.size());
  if (unpaired.size() < filters.size()) unpaired.resize(filters.size());
  // Branch-free: each id goes to both lists, and only one of them moves on.
  std::size_t p = 0, u = 0;
  for (const std::uint32_t k : active) {
    const Filter f = filters[k];
    const bool can = may_pair(f, groups, masks);
    pairable[p] = k;
    unpaired[u] = k;
    p += can;
    u += !can;
  }
  return {std::span<const std::uint32_t>(pairable.data(), p), std::span<const std::uint32_t>(unpaired.data(), u)};
}

Status PipelineDetector::draw_frame(const CameraRig& cam, const Camera&, const FrameInput& in, int threads) {
  draw_.build(in, &static_set_);
  return rasterize(cam, draw_.objects, threads);
}

void PipelineDetector::for_chunks_of(std::size_t n, const std::function<void(std::size_t, std::size_t)>& f) {
  const ExecutorScope scope(config_.executor);
  const int threads = frame_threads();
  for_chunks(n, ranges_for(n, threads), [&](std::size_t b, std::size_t e, std::size_t) { f(b, e); });
}

Status PipelineDetector::validate_objects(const Shapes& objects) {
  const std::size_t n = objects.size();
  const ExecutorScope scope(config_.executor);
  const int threads = frame_threads();
  std::atomic<bool> all_valid{true};
  for_chunks(n, ranges_for(n, threads), [&](std::size_t b, std::size_t e, std::size_t) {
    const bool ok = objects.is_box() ? boxes_all_valid(objects.boxes.subspan(b, e - b))
                                     : spheres_all_valid(objects.spheres.subspan(b, e - b));
    if (!ok) all_valid.store(false, std::memory_order_relaxed);
  });
  if (all_valid.load(std::memory_order_relaxed) &&
      n <= static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
    return {};
  return Backend::validate_objects(objects);  // finds the first bad object and names it
}

Status PipelineDetector::run_frame(const FrameInput& in, FrameResult& out) {
  const Camera* camera = in.camera;
  const bool callers_map = !in.id_map.empty();
  if (in.gl_id_texture != 0)
    return Status::failure(ErrorKind::unsupported_input,
                           "FrameInput::gl_id_texture is for the gl backend; the " + std::string(name()) +
                               " backend reads the caller's visibility map from FrameInput::id_map");
  // Every parallel stage of this frame runs on the caller's executor, or on viscd's pool.
  const ExecutorScope scope(config_.executor);
  const int threads = frame_threads();
  // The moving objects, then the static set's: drawn, always active, never paired with each other
  // (appended here, or kept by the backend: handles_static()).
  const bool own_static = handles_static();
  all_.build(in, own_static ? nullptr : &static_set_);
  const std::size_t n = all_.moving, total = all_.total();
  FrameStats& stats = out.stats;
  stats = FrameStats{};
  stats.objects = static_cast<std::uint32_t>(n);
  stats.static_objects = static_cast<std::uint32_t>(static_set_.size());
  stats.has_camera = camera != nullptr;
  stats.has_pixels = counts_pixels(in, config_);
  Stopwatch sw;

  int bits = 0;
  std::optional<CameraRig> rig;
  if (callers_map) {
    // The caller's map: no stage 1; counted, then culled exactly as a map of our own.
    map_ = VisibilityMap{};
    stats.ms(Stage::visibility) = sw.lap();
    if (!count_ids(in.id_map, n, threads, hist_, count_scratch_)) return id_map_error(in.id_map, in.id_map_width, n);
    stats.ms(Stage::count) = sw.lap();
    const double scale = map_pixel_scale(camera, in.id_map_width, in.id_map_height);
    bits = cull_in_parallel(std::span<const std::uint32_t>(hist_).subspan(1, n), scale, config_, in.always_active,
                            threads, out.pixels, active_, cull_scratch_, stats);
    stats.ms(Stage::cull) = sw.lap();
  } else if (renders_own_map(in, config_)) {
    const MapSize map = map_size(config_, *camera);
    rig.emplace(*camera, map.width, map.height);
    map_.resize(map.width, map.height, config_.shade);
    if (Status s = draw_frame(*rig, *camera, in, threads); !s) return s;  // static objects occlude
    stats.ms(Stage::visibility) = sw.lap();
    if (own_static && !static_set_.empty() && map_.has_counts && map_.counts.size() == n) {
      counts_.assign(map_.counts.begin(), map_.counts.end());  // the moving objects', static occlusion taken off
    } else if (own_static && !static_set_.empty()) {
      // Ids above n are the static layer's: counted together in the bin above the moving objects
      // and left out, so that counting costs the pixels and n, not the static count.
      (void)count_ids(map_.ids, n, threads, hist_, count_scratch_);
      counts_.assign(hist_.begin() + 1, hist_.begin() + 1 + static_cast<std::ptrdiff_t>(n));
    } else {
      count_pixels(map_, n + static_set_.size(), threads, counts_, hist_, count_scratch_);
    }
    stats.ms(Stage::count) = sw.lap();
    bits = cull_in_parallel(std::span<const std::uint32_t>(counts_).first(n), rig->pixel_scale, config_,
                            in.always_active, threads, out.pixels, active_, cull_scratch_, stats);
    stats.ms(Stage::cull) = sw.lap();
  } else {
    // No camera, or one whose map nothing would use (culling off, fixed bits, no shading, no
    // pixels asked for): no stages 1-3, every object active.
    map_ = VisibilityMap{};
    out.pixels.clear();
    // Every object. Active lists ascend without repeats, so one of n entries ending at n - 1 is
    // already 0 .. n - 1 (kept from the last frame: it is 4 MB at 10^6 objects).
    if (active_.size() != n || (n > 0 && active_.back() != n - 1)) {
      active_.resize(n);
      parallel_for(n, threads, [&](std::size_t k) { active_[k] = static_cast<std::uint32_t>(k); });
    }
    stats.active = static_cast<std::uint32_t>(n);
    bits = choose_bits(config_, false, 0.0, n);
  }
  // Static objects are never culled (and stats.active counts the moving ones).
  if (total > n) {
    active_.reserve(total);
    for (std::size_t k = n; k < total; ++k) active_.push_back(static_cast<std::uint32_t>(k));
  }
  const std::span<const Filter> filters = all_.filters;

  bool followed = false;
  if (own_static)
    if (Status s = follow_change(in, all_.objects, active_, filters, bits, threads, out.pairs, stats, followed); !s)
      return s;
  if (followed) {
    (void)sw.lap();  // its stages timed themselves
  } else {
    // Objects whose filters pair them with nothing active stay out of the tree.
    std::span<const std::uint32_t> pairable = active_, unpaired;
    if (!filters.empty()) {
      const FilterSplit split = own_static ? split_by_filters(active_, filters, pairable_, unpaired_,
                                                              static_set_.groups(), static_set_.masks())
                                           : split_by_filters(active_, filters, pairable_, unpaired_);
      pairable = split.pairable;
      unpaired = split.unpaired;
      stats.ms(Stage::cull) += sw.lap();
    }

    const std::uint32_t static_from = own_static ? ~0u : static_cast<std::uint32_t>(n);
    if (Status s = broadphase(all_.objects, pairable, unpaired, filters, static_from, bits, threads, out.pairs, stats);
        !s)
      return s;
  }
  stats.pairs = out.pairs.size();

  sw.lap();
  // States: culled, free when active, colliding when in a pair. The pairs' writes may meet at an
  // object from two threads (the same value), so they are relaxed atomic stores.
  out.state.resize(n);
  all_.report(out.pairs);  // appended static objects as static_index(slot)
  // The objects in pairs, marked in a bitset per chunk of the pairs (an eighth of a byte per
  // object: it stays in cache, where marking the states themselves at random would miss it), then
  // the states written in order from the bitsets.
  // A followed frame may know them already (cpu/rest_set.hpp keeps them as its candidates change:
  // marking them from 5 * 10^5 pairs had cost about 1 ms, an eighth of a frame with 1 % moving).
  const std::size_t words = (n + 63) / 64;
  const std::uint64_t* const known = followed && active_.size() == total ? followed_pair_bits() : nullptr;
  const std::size_t chunks =
      known ? 0 : std::min<std::size_t>(threads_for(out.pairs.size(), threads), out.pairs.size());
  resize_with_headroom(in_pair_, chunks * words);
  for_chunks(chunks == 0 ? 0 : out.pairs.size(), chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
    std::uint64_t* mark = in_pair_.data() + c * words;
    std::fill(mark, mark + words, std::uint64_t{0});
    for (std::size_t k = b; k < e; ++k) {
      const Pair& p = out.pairs[k];  // i is moving (no pair of two static objects); j may be static
      mark[p.i >> 6] |= std::uint64_t{1} << (p.i & 63);
      if (p.j < n) mark[p.j >> 6] |= std::uint64_t{1} << (p.j & 63);
    }
  });
  auto in_pair = [&](std::size_t w) {
    if (known) return known[w];
    std::uint64_t m = 0;
    for (std::size_t c = 0; c < chunks; ++c) m |= in_pair_[c * words + w];
    return m;
  };
  if (active_.size() == total) {
    // free is 1 and colliding 2: eight states at a time are 0x01 per byte plus the mask's bits
    // spread one to a byte (a table of 256).
    static_assert(static_cast<int>(ObjectState::free) == 1 && static_cast<int>(ObjectState::colliding) == 2);
    static constexpr auto kSpread = [] {
      std::array<std::uint64_t, 256> t{};
      for (std::uint32_t b = 0; b < 256; ++b)
        for (std::uint32_t bit = 0; bit < 8; ++bit) t[b] |= std::uint64_t{((b >> bit) & 1u) + 1u} << (8 * bit);
      return t;
    }();
    auto* const state = reinterpret_cast<std::uint8_t*>(out.state.data());
    parallel_for(words, threads, [&](std::size_t w) {
      const std::uint64_t m = in_pair(w);
      const std::size_t first = w * 64, end = std::min(n, first + 64);
      if (end - first == 64) {
        for (std::size_t b = 0; b < 8; ++b) {
          const std::uint64_t v = kSpread[(m >> (8 * b)) & 0xFF];
          std::memcpy(state + first + 8 * b, &v, sizeof v);
        }
        return;
      }
      for (std::size_t k = first; k < end; ++k)
        out.state[k] = (m >> (k & 63)) & 1 ? ObjectState::colliding : ObjectState::free;
    });
  } else {
    std::fill(out.state.begin(), out.state.end(), ObjectState::culled);
    for (std::uint32_t k : active_)
      if (k < n) out.state[k] = ObjectState::free;
    parallel_for(words, threads, [&](std::size_t w) {
      for (std::uint64_t m = in_pair(w); m; m &= m - 1)
        out.state[w * 64 + static_cast<std::size_t>(std::countr_zero(m))] = ObjectState::colliding;
    });
  }
  stats.ms(Stage::query) += sw.lap();

  if (rig && config_.shade) {
    shade(*rig, map_, out.state, threads, out.image);
    out.image_width = map_.width;
    out.image_height = map_.height;
    stats.ms(Stage::shade) = sw.lap();
  } else {
    out.image.clear();
    out.image_width = out.image_height = 0;
  }
  return {};
}

}  // namespace viscd::detail
