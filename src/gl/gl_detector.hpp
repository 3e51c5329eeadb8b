#pragma once
// The gl backend: every stage of the frame (docs/architecture.md) runs in OpenGL 4.5 compute
// shaders (and one instanced draw for the visibility map). Two modes (GlOptions::sync_layout,
// docs/gl.md):
//   default (sync_layout = false): no host wait between the start of the frame and its final
//      readback. m and the Morton layout are chosen on the host (core/morton.hpp, as the cpu
//      backend) from the PREVIOUS frame's FrameInfo (active count, active-centre bounds,
//      diameter sum, pixel total), which the host read with that frame's pair count. Every
//      pass after culling is sized by this frame's active count n through indirect dispatch
//      (DispatchArgs, written on the GPU from FrameInfo), and reads n from FrameInfo. The
//      first frame, and a frame whose N or camera presence differs from the previous frame's,
//      run as sync_layout.
//   sync_layout = true: one wait after stage 3 for this frame's FrameInfo; m and the layout are
//      then exactly the cpu backend's (bit-identical codes).
// In both modes the frame ends with one wait, for FrameInfo (the pair count: grow the pair
// buffer and re-run on overflow; n and the values the next frame uses), then the results the
// caller asked for (pairs, states, pixels, image) are read back.
// The decisions that do not depend on where a stage runs (map size, m, the Morton layout and
// grid, culling, shading) are core's (src/core), shared with the cpu backend.

#include <array>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "core/backend.hpp"
#include "core/geometry.hpp"
#include "core/lbvh.hpp"
#include "core/morton.hpp"
#include "core/visibility.hpp"
#include "gl/context.hpp"
#include "gl/objects.hpp"
#include "gl/program.hpp"
#include "gl/shaders/shared/layout.h"
#include "viscd/gl.hpp"

namespace viscd::gl {

class GlDetector final : public detail::Backend {
 public:
  [[nodiscard]] static Result<std::unique_ptr<GlDetector>> create(const Config& config, const GlOptions& options);
  ~GlDetector() override;

  void wait_for_stage_times(FrameStats& stats) override;
  [[nodiscard]] std::string_view name() const override { return "gl"; }
  [[nodiscard]] std::uint64_t memory_bytes() const override;
  [[nodiscard]] const GlOptions& options() const { return options_; }
  void set_options(const GlOptions& options) { options_ = options; }
  /// "llvmpipe (LLVM 15.0.6, 256 bits) | 4.5 (Core Profile) Mesa 22.3.6"
  [[nodiscard]] const std::string& device() const { return ctx_->description(); }

  // ---- stage access for tests (each makes the context current and checks GL errors) ----

  /// Stages 5-8 alone over a given active set (ascending), with the layout and bounds computed
  /// on the host as the cpu backend does. Writes sorted pairs, stats.bits/layout/pairs.
  [[nodiscard]] Status run_broadphase(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, int bits,
                                      std::vector<Pair>& pairs, FrameStats& stats);
  /// After a frame or run_broadphase: sorted codes (widened), sorted object ids, the tree with
  /// its leaf boxes (a core Lbvh, ready for validate_lbvh), and the current pair capacity.
  [[nodiscard]] std::vector<std::uint64_t> read_sorted_codes();
  [[nodiscard]] std::vector<std::uint32_t> read_sorted_ids();
  void read_tree(detail::Lbvh& bvh, std::vector<detail::Aabb>& leaf_boxes);
  [[nodiscard]] std::uint32_t pair_capacity() const { return pair_capacity_; }
  /// Frames so far that waited mid-frame for their own FrameInfo (sync_layout, a first frame,
  /// or a change of N or camera presence); default-mode frames do not count.
  [[nodiscard]] std::uint64_t mid_frame_waits() const { return mid_frame_waits_; }
  /// After a frame with a camera: the id map, rows top to bottom (object index + 1, 0 = none).
  [[nodiscard]] std::vector<std::uint32_t> read_id_map();
  /// Stage 2 alone on a given id map (rows top to bottom) of `objects` objects, in the current
  /// counter mode.
  [[nodiscard]] Result<std::vector<std::uint32_t>> count_id_map(std::span<const std::uint32_t> ids, int width,
                                                                int height, std::uint32_t objects);

 protected:
  /// The frame. Filters, the caller's id map and a gl id texture are refused (not taken yet).
  /// Queries: the base class's brute force over the active spheres (answers_queries() is false).
  [[nodiscard]] Status run_frame(const FrameInput& input, FrameResult& out) override;
  // Queries: the frame's spheres and states stay on the GPU; the first query after a frame reads
  // them back once (no host copy in frames nobody queries), then Detector's brute force.
  [[nodiscard]] bool answers_queries() const override { return true; }
  [[nodiscard]] bool query_ray(const Ray& ray, RayHit& hit) override;
  void query_ray_all(const Ray& ray, std::vector<RayHit>& hits) override;
  void query_overlap(const Sphere& sphere, std::vector<std::uint32_t>& indices) override;
  void read_active_spheres();

 private:
  GlDetector(const Config& config, const GlOptions& options) : Backend(config), options_(options) {}
  [[nodiscard]] Status init();
  [[nodiscard]] Status gl_errors(const char* where);
  void upload_spheres(std::span<const Sphere> spheres);

  // The frame's stages, in order (gl_detector.cpp unless named).
  /// Uploads the spheres (and filters), sizes the per-object buffers, zeroes FrameInfo, sets up
  /// the camera and the map's pixel scale.
  void begin_frame(const FrameInput& in);
  /// Stages 1-2 (visibility.cpp): the G-buffer and the pixel count per object.
  [[nodiscard]] Status render_visibility(std::uint32_t objects);
  /// Stage 2 on the caller's map (visibility.cpp): FrameInput::id_map uploaded, or
  /// FrameInput::gl_id_texture checked and read.
  [[nodiscard]] Status count_callers_map(const FrameInput& in);
  /// Stage 3: pixels, active flags and first states; with filters, the objects that can pair with
  /// none out of the tree; the compaction into the tree's list; its count in FrameInfo and the
  /// indirect dispatch sizes from it.
  void cull(std::uint32_t objects);
  /// Stage 4's inputs on the GPU: the active centres' bounds and diameter sum into FrameInfo.
  void measure_extent();
  /// Stage 4 on the host: m and the Morton layout from this frame's FrameInfo (a mid-frame
  /// wait) or from the previous frame's (default mode, no wait).
  struct LayoutChoice {
    detail::MortonLayout layout;
    detail::Aabb bounds;
    std::uint32_t n_bound = 0;  // sizes the buffers of stages 5-8: n when known, else N
  };
  [[nodiscard]] LayoutChoice choose_layout(std::uint32_t objects, bool has_pixels, FrameStats& stats);
  /// After the broadphase: this frame's active count and mu into stats, and kept for the next frame.
  void remember_frame(std::uint32_t objects, bool has_pixels, FrameStats& stats);
  /// A caller's map holding ids above N: the frame's error (after the final wait).
  [[nodiscard]] Status id_check(const FrameInput& in) const;
  /// Both objects of every pair become colliding (the cull pass wrote free / culled).
  void mark_colliding(std::uint32_t pairs);
  /// States and pixels back to the host.
  void read_states_and_pixels(std::uint32_t objects, bool has_pixels, FrameResult& out);
  /// Stage 9 (visibility.cpp) and the image back to the host.
  void shade(FrameResult& out);

  // visibility.cpp
  void ensure_map(int w, int h);
  void draw_gbuffer(std::uint32_t n);
  /// Counts the ids of `ids` (w x h) into counts_[0..n) in the given mode (ssbo: ids above n
  /// into FrameInfo.id_check).
  [[nodiscard]] Status count_pixels(GLuint ids, int w, int h, std::uint32_t n, GlCounter mode);
  void make_mesh();
  void set_camera_uniforms(const Program& p) const;

  // broadphase.cpp
  /// Exclusive scan of n uints (three dispatches, reduce-then-scan); leaves the total in
  /// block_sums_[ceil(n / VISCD_SCAN_BLOCK)]. Used over all N objects by the compaction.
  void scan(GLuint in, GLuint out, std::uint32_t n);
  /// Writes DispatchArgs from FrameInfo.active_count (one invocation on the GPU).
  void write_dispatch_args();
  /// Sorts keys[0] (+ values[0]) by their low key_bits; returns which of the two buffers
  /// holds the result. n_from_info: the key count is FrameInfo.active_count on the GPU, the
  /// passes are dispatched indirectly from it and n only bounds it (buffer sizes); otherwise
  /// the count is n and the host sizes the passes.
  int radix_sort(Buffer* keys, Buffer* values, std::uint32_t n, int key_bits, bool n_from_info);
  /// Stages 5-8 over FrameInfo.active_count active objects (on the GPU), dispatched from
  /// DispatchArgs; `n_bound` >= that count sizes the buffers.
  /// Ends with the frame's one wait: frame_info_ holds this frame's FrameInfo afterwards.
  [[nodiscard]] Status broadphase(std::uint32_t n_bound, std::uint32_t objects, const detail::MortonLayout& layout,
                                  const detail::Aabb& bounds, std::vector<Pair>& pairs, FrameStats& stats);
  void reserve_broadphase(std::uint32_t n);
  /// Dispatches `p` with the work-group count at `offset` in DispatchArgs.
  void dispatch_indirect(const Program& p, GLintptr offset) const;

  // timers (gl_detector.cpp)
  // A stage's GPU time is the sum of up to kTimerParts intervals, so that a stage split by a host
  // wait (stage 8: traversal | wait for the pair count | pair sort | states) counts GPU work only.
  static constexpr std::size_t kTimerParts = 3;
  void stage_begin(Stage s, std::size_t part = 0);
  void stage_end(Stage s, std::size_t part = 0);
  void read_timers(FrameStats& stats);
  Status detect_frame(const FrameInput& in, FrameResult& out);

  GlOptions options_;
  std::unique_ptr<Context> ctx_;
  // Programs.
  Program scan_local_, scan_blocks_, scan_add_, count_, cull_, pairable_, compact_, dispatch_args_, bounds_,
      bounds_fold_, morton_, sort_local_, radix_hist_, radix_scan_, radix_scatter_, build_, fit_, query_, state_,
      shade_, impostor_, mesh_, count_atomic_;
  std::uint32_t count_atomic_n_ = 0;  // N the atomic_uint program was built for
  // Buffers (see shaders/shared/layout.h for their contents).
  Buffer filters_, spheres_, counts_, pixels_, flags_, scan_out_, block_sums_, active_, info_, partials_, hist_,
      dispatch_, nodes_, parent_, arrivals_, sorted_, leaf_boxes_, pairs_, pairs_tmp_, states_, image_;
  Buffer keys_[2], values_[2];
  Buffer mesh_vbo_, mesh_ibo_;
  GLsizei mesh_indices_ = 0;
  int sorted_in_ = 0;         // which keys_/values_ holds the last sorted codes
  std::uint32_t last_n_ = 0;  // active count of the last broadphase
  std::uint32_t pair_capacity_ = 0;
  // Driver limits, read once: work groups per dispatch (x), and the atomic_uint counters.
  std::uint32_t max_groups_ = 65535;
  GLint max_fragment_counters_ = 0, max_counter_buffer_bytes_ = 0;
  // This frame's camera over its map (nullopt without a camera), and the states' readback.
  std::optional<detail::CameraRig> rig_;
  double pixel_scale_ = 1.0;  // screen pixels per map pixel (1 without a camera)
  bool has_pixels_ = false;   // pixels are counted this frame (a camera, or the caller's map)
  bool has_filters_ = false;  // FrameInput::filters were given this frame
  std::vector<std::uint32_t> state_words_;
  // The last frame's active spheres for queries, read back on the first query after it.
  bool query_copy_ready_ = false;
  std::uint32_t query_objects_ = 0;  // N of the last frame
  std::vector<Sphere> query_all_, query_active_;
  std::vector<std::uint32_t> query_ids_;
  // This frame's FrameInfo, read back once at the end of the broadphase (with the pair count).
  shader::FrameInfo frame_info_{};
  // The previous frame's values, the default mode's source of m, the layout and the bounds.
  bool have_prev_ = false;
  shader::FrameInfo prev_info_{};   // its active count, active-centre bounds, diameter sum
  double prev_mean_pixels_ = 0.0;   // its mu
  std::uint32_t prev_objects_ = 0;  // its N
  bool prev_pixels_ = false;        // it counted pixels (a camera or the caller's map)
  std::uint64_t mid_frame_waits_ = 0;
  // G-buffer.
  Texture ids_tex_, depth_tex_, normal_tex_, zbuffer_;
  // Nearest sampling for the id map, whatever the texture's own filters (an integer texture
  // with a linear filter is incomplete and reads as 0): bound while counting.
  Sampler nearest_;
  Framebuffer gbuffer_, empty_fbo_;
  VertexArray empty_vao_, mesh_vao_;
  int map_w_ = 0, map_h_ = 0;
  // Timers: GL_TIMESTAMP pairs per stage and part, two frames in flight; read one frame late.
  std::array<std::array<Query, 2 * kStageCount * kTimerParts>, 2> timers_;
  std::array<std::array<bool, kStageCount * kTimerParts>, 2> timer_used_{};
  int timer_frame_ = 0;
  bool timers_ok_ = false;
};

}  // namespace viscd::gl
