#pragma once
/// \file config.hpp
/// Settings of a detector. Every field has a documented default; `Config{}` is the paper's setup.

#include <cstddef>
#include <cstdint>

#include "viscd/executor.hpp"

namespace viscd {

/// Morton code width m. `adaptive` picks 16/32/64 from the mean pixel count mu (paper Eq. 1).
enum class Bits : std::uint8_t { adaptive = 0, b16 = 16, b32 = 32, b64 = 64 };

/// How Morton bits are laid out over the axes.
enum class Layout : std::uint8_t {
  extended,  ///< axes by extent, few bits on the flattest axis (paper Table 2; docs/architecture.md)
  plain,     ///< classic interleaving x,y,z with equal bits: 5/5/5, 10/10/10 or 21/21/21
};

/// Which SIMD kernels the cpu backend may use (stage 8's lanes, the rasterizer's tiles, queries).
/// The best the CPU has is used unless this lowers it; results are equal bit for bit whatever the
/// choice (for tests and measurements).
enum class Simd : std::uint8_t {
  best,    ///< the widest the CPU offers (AVX-512F when present, else SSE2)
  sse2,    ///< at most SSE2
  scalar,  ///< plain C++
};

/// Settings shared by every backend. Defaults follow the paper's experiments.
struct Config {
  /// Culling threshold lambda, in screen pixels: objects covering fewer are culled. Default 200.
  /// An object is active exactly when FrameResult::pixels[k] >= lambda (the float reported).
  float lambda = 200.0f;
  /// Adaptive Morton width (the paper's Eq. (1), its thresholds a and b): with mu the mean screen
  /// pixels per object, m = 16 if mu < pixels_for_32_bits, 32 if mu < pixels_for_64_bits, else 64.
  /// Defaults 100 (a) and 400 (b). Beyond the paper, 16 becomes 32 when more than 131 072 objects
  /// are active: 16-bit codes have too few cells for them (docs/architecture.md, "Morton width").
  float pixels_for_32_bits = 100.0f;
  float pixels_for_64_bits = 400.0f;
  /// Morton width: adaptive (default) or fixed 16/32/64. Pairs are exact for every choice.
  Bits bits = Bits::adaptive;
  /// Bit layout, extended (default) or plain.
  Layout layout = Layout::extended;
  /// Cull objects below lambda pixels. Applies only when a camera or the caller's id map
  /// (FrameInput::id_map) is given. Default on.
  bool culling = true;
  /// Visibility-map resolution; 0 x 0 (default) means the camera's screen resolution. Counts
  /// on a smaller or larger map are scaled by screen area / map area before lambda and mu apply.
  int map_width = 0;
  int map_height = 0;
  /// Produce the shaded image (stage 9) in FrameResult::image. Default off.
  bool shade = false;
  /// Count every object's pixels (FrameResult::pixels, mu) even when no stage needs them. With a
  /// camera the detector renders and counts a visibility map of its own only when something uses
  /// it: culling, adaptive bits (mu picks m), shading, or this. Off (default), a frame with a
  /// camera, culling off and a fixed bit count renders no map: the paper's baseline, which pays
  /// for the broadphase alone. Nor does one with adaptive bits whose m no map can change: culling
  /// off, more than 131 072 objects and fewer screen pixels than pixels_for_32_bits per object
  /// (mu is then below a, and m is 32). The caller's id map is always counted (the count also
  /// checks it).
  bool report_pixels = false;
  /// Report contact events: FrameResult::began and ::ended, the pairs that began and ended since
  /// the previous detect() of this detector (Detector::reset_events() forgets that frame). Objects
  /// are compared by index: a pair whose object left the active set (culled, filtered, or an index
  /// beyond this frame's N) ends. Default off.
  bool contact_events = false;
  /// Hard cap on the memory pairs may take, in bytes (8 per pair); 0 (default) = no cap.
  /// A frame with more pairs fails with an error; it never truncates. The cap is enforced while
  /// pairs are found, before their memory is taken, so the error names the count found when the
  /// search stopped ("at least N pairs"), and a failing frame holds about the cap (plus a few
  /// hundred KiB) in pair buffers.
  std::size_t pair_memory_cap = 0;
  /// Worker threads for the cpu backend; 0 (default) = all hardware threads, 1 = serial.
  /// More than the machine has (or than `executor` offers) are clamped; negative is an error.
  int threads = 0;
  /// Where the cpu backend's parallel stages run: the caller's job system (not owned; it must
  /// outlive the detect() calls), or nullptr (default) for viscd's own pool, whose threads sleep
  /// while there is no work and whose caller works too (docs/architecture.md, "Threads").
  Executor* executor = nullptr;
  /// cpu backend: keep the last frame's object order while it stays good, skipping stages 4-6
  /// (docs/architecture.md, "The cpu broadphase, stage by stage"). Pairs are exact either way.
  /// Default on; off, every frame sorts (for measurements and tests of the sort).
  bool keep_order = true;
  /// cpu backend: the widest SIMD kernels allowed. Default Simd::best.
  Simd simd = Simd::best;
  /// cpu backend: cost follows change (docs/architecture.md, "Resting objects"). When most
  /// objects keep their bounds from frame to frame, the detector keeps them in trees across
  /// frames with their candidate pairs, and a frame costs what the objects that moved and their
  /// neighbours cost (plus a pass comparing bounds, unless FrameInput::moved names the movers).
  /// Results are those of a frame that rebuilt everything. Off, every frame rebuilds. Default on.
  bool follow_change = true;
  /// cpu backend, with follow_change: how far an object may move and stay resting, in world
  /// units. An object rests while its box (a sphere's conservative box) stays inside the box it
  /// was last placed with, grown by this margin on every side; its candidate pairs (fat boxes
  /// that overlap) are carried over and re-tested exactly each frame it changes. 0 (default):
  /// an object rests only while its bounds stay bit for bit the same, and no candidate is ever
  /// re-tested. A margin pays where objects jiggle in place (a settled granular pile, the bodies of
  /// an island a physics engine keeps awake): about the distance they drift in a few frames
  /// (viscd::BulletBroadphase defaults to 0.05, btDbvtBroadphase's margin). Must be finite and
  /// >= 0.
  float rest_margin = 0.0f;
  /// cpu backend, with follow_change: margins of their own for the objects that keep moving. An
  /// object that leaves its bounds in two frames in a row is placed again with a margin of
  /// move_margin times how far it moved since the last frame (at most half a sphere's radius, a
  /// quarter of a box's longest side; none when it moved farther than that), and rests while it
  /// stays inside them: a body that keeps moving is placed again every few frames instead of
  /// every frame, its candidates re-tested exactly meanwhile. Objects that come to rest get their
  /// exact bounds back (with rest_margin 0). The default, 8, measured best of 2, 4 and 8 where
  /// 1-10 % of 10^6 objects keep moving (docs/benchmarks.md, "Margins of their own, kept"); 0
  /// places every object that changes again. Results are the same either way. Must be finite and
  /// >= 0.
  float move_margin = 8.0f;
  /// Check FrameInput::moved: every object the list leaves out is compared with the previous
  /// frame, and a frame where one of them changed fails with ErrorKind::invalid_input naming it
  /// (a pass over every object: for tests and debug builds of an engine). Default off.
  bool verify_moved = false;
};

}  // namespace viscd
