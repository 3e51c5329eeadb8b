// Stages 5-8 of the gl backend (broadphase.hpp): Morton codes, sort, Karras build, fit, query
// with pair buffer growth, pair sort, states.
#include "gl/broadphase.hpp"

#include <algorithm>
#include <bit>
#include <cstddef>
#include <utility>

#include "core/frame_rules.hpp"
#include "viscd/assert.hpp"

namespace viscd::gl {
Status Broadphase::init() {
  if (Status s = build_compute_programs({{&morton_, "morton.comp"},
                                         {&build_, "lbvh_build.comp"},
                                         {&fit_, "lbvh_fit.comp"},
                                         {&query_, "lbvh_query.comp"},
                                         {&state_, "state.comp"}});
      !s)
    return s;
  if (Status s = sort_.init(); !s) return s;
  pair_capacity_ = std::max<std::uint32_t>(1, options_.initial_pair_capacity);
  pairs_.reserve(static_cast<GLsizeiptr>(pair_capacity_) * 8);
  return {};
}

std::uint64_t Broadphase::buffer_bytes() const {
  std::uint64_t b = sort_.buffer_bytes();
  for (const Buffer* buf : {&keys_[0], &keys_[1], &values_[0], &values_[1], &nodes_, &parent_, &arrivals_, &sorted_,
                            &leaf_boxes_, &pairs_, &pairs_tmp_})
    b += static_cast<std::uint64_t>(buf->size());
  return b;
}

void Broadphase::reserve(std::uint32_t n) {
  const auto bytes = [n](GLsizeiptr per) { return per * static_cast<GLsizeiptr>(n); };
  for (int k = 0; k < 2; ++k) {
    keys_[k].reserve(bytes(8));
    values_[k].reserve(bytes(4));
  }
  nodes_.reserve(bytes(64));
  parent_.reserve(bytes(8));
  arrivals_.reserve(bytes(4));
  sorted_.reserve(bytes(16));
  leaf_boxes_.reserve(bytes(24));
}

// n = FrameInfo.active_count is read on the GPU by every pass (codes, sort, build, fit, query),
// and each pass is dispatched indirectly from DispatchArgs (written from n on the GPU); the host
// only knows the bound n_bound >= n, which sizes the buffers. In the default mode n_bound is N;
// in sync mode, and in the tests' GlInspector::run_broadphase, it is n itself.
Result<std::uint32_t> Broadphase::run(std::uint32_t n_bound, std::uint32_t objects, std::uint32_t static_from,
                                      const detail::MortonLayout& layout, const detail::Aabb& bounds,
                                      FrameStats& stats) {
  const std::uint32_t n = n_bound;
  reserve(n);
  constexpr GLintptr per_object = offsetof(shader::DispatchArgs, per_object);
  frame_.info.bind_storage(VISCD_BIND_INFO);

  // Stage 5: codes, on the shared quantisation grid (core/morton.hpp), so they equal the cpu
  // backend's bit for bit.
  timers_.begin(Stage::codes);
  {
    const detail::MortonGrid grid = detail::morton_grid(layout, bounds);
    GLint position[96] = {};
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < layout.axis_bits[a]; ++b) position[32 * a + b] = layout.position[a][b];
    const GLuint p = morton_.get();
    glProgramUniform3dv(p, morton_.uniform("u_lo"), 1, grid.lo.data());
    glProgramUniform3dv(p, morton_.uniform("u_scale"), 1, grid.scale.data());
    glProgramUniform3dv(p, morton_.uniform("u_max_cell"), 1, grid.max_cell.data());
    glProgramUniform3i(p, morton_.uniform("u_axis_bits"), layout.axis_bits[0], layout.axis_bits[1],
                       layout.axis_bits[2]);
    glProgramUniform1iv(p, morton_.uniform("u_position"), 96, position);
    frame_.spheres.bind_storage(VISCD_BIND_SPHERES);
    frame_.active.bind_storage(VISCD_BIND_ACTIVE);
    keys_[0].bind_storage(VISCD_BIND_KEYS_OUT);
    values_[0].bind_storage(VISCD_BIND_VALUES_OUT);
    frame_.dispatch_indirect(morton_, per_object);
    barrier();
  }
  timers_.end(Stage::codes);

  // Stage 6: sort (key, object index); values start ascending, the sort is stable.
  timers_.begin(Stage::sort);
  sorted_in_ = sort_.sort(keys_, values_, n, layout.bits, true);
  timers_.end(Stage::sort);

  // Stage 7: build, then fit (leaf boxes: conservative_box() of a sphere, a box itself).
  timers_.begin(Stage::build);
  keys_[sorted_in_].bind_storage(VISCD_BIND_KEYS_IN);
  nodes_.bind_storage(VISCD_BIND_NODES);
  parent_.bind_storage(VISCD_BIND_PARENT);
  arrivals_.bind_storage(VISCD_BIND_ARRIVALS);  // zeroed by the build, one per internal node
  glProgramUniform1i(build_.get(), build_.uniform("u_bits"), layout.bits);
  frame_.dispatch_indirect(build_, offsetof(shader::DispatchArgs, per_node));
  barrier();
  timers_.end(Stage::build);
  timers_.begin(Stage::fit);
  frame_.spheres.bind_storage(VISCD_BIND_SPHERES);
  values_[sorted_in_].bind_storage(VISCD_BIND_VALUES_IN);
  sorted_.bind_storage(VISCD_BIND_SORTED);
  leaf_boxes_.bind_storage(VISCD_BIND_LEAF_BOXES);
  arrivals_.bind_storage(VISCD_BIND_ARRIVALS);
  frame_.info.bind_storage(VISCD_BIND_INFO);
  if (frame_.has_boxes) frame_.boxes.bind_storage(VISCD_BIND_BOXES);
  glProgramUniform1ui(fit_.get(), fit_.uniform("u_boxes"), frame_.has_boxes ? 1u : 0u);
  frame_.dispatch_indirect(fit_, per_object);
  barrier();
  timers_.end(Stage::fit);

  // Stage 8: query; on overflow grow the buffer to the exact count and run it again. Its GPU
  // time is three intervals (StageTimers parts): the traversal (the last attempt), the pair
  // sort, and the states (mark_colliding); the host waits between them are not GPU work.
  // The previous frame's pair sort may have left its smaller buffer (sized for that frame's
  // count) as pairs_: make sure pairs_ holds the pair_capacity_ pairs the query may write.
  pairs_.reserve(static_cast<GLsizeiptr>(pair_capacity_) * 8);
  std::uint32_t count = 0;
  for (int attempt = 0;; ++attempt) {
    VISCD_ASSERT(attempt < 2, "the pair count is exact, one re-run suffices");
    const GLuint zero = 0;
    glNamedBufferSubData(frame_.info.get(), offsetof(shader::FrameInfo, pair_count), 4, &zero);
    pairs_.bind_storage(VISCD_BIND_PAIRS);
    glProgramUniform1ui(query_.get(), query_.uniform("u_capacity"), pair_capacity_);
    glProgramUniform1ui(query_.get(), query_.uniform("u_has_filters"), frame_.has_filters ? 1u : 0u);
    glProgramUniform1ui(query_.get(), query_.uniform("u_boxes"), frame_.has_boxes ? 1u : 0u);
    glProgramUniform1ui(query_.get(), query_.uniform("u_static_from"), static_from);
    if (frame_.has_filters) frame_.filters.bind_storage(VISCD_BIND_FILTERS);
    timers_.begin(Stage::query, 0);
    frame_.dispatch_indirect(query_, per_object);
    barrier();
    timers_.end(Stage::query, 0);
    // The frame's one wait (both modes): the whole FrameInfo, i.e. the pair count and this
    // frame's n, bounds, diameter sum and pixel total (the next frame's layout inputs).
    glGetNamedBufferSubData(frame_.info.get(), 0, sizeof frame_info_, &frame_info_);
    count = frame_info_.pair_count;
    last_n_ = frame_info_.active_count;
    if (Status s = detail::check_pair_cap(count, config_.pair_memory_cap); !s) return Result<std::uint32_t>::failure(s);
    if (count <= pair_capacity_) break;
    // A pair count beyond 2^32 - 1 would wrap the counter; N < 2^29 with our spheres cannot
    // fill 2^32 pairs on any machine this runs on, and the cap check above catches it first.
    pair_capacity_ = count;
    pairs_.reserve(static_cast<GLsizeiptr>(pair_capacity_) * 8);
  }
  // Sort the pairs as 64-bit keys (i << 32 | j): x = j, y = i; i, j < objects (static ones
  // included: the caller reports them afterwards).
  pairs_tmp_.reserve(static_cast<GLsizeiptr>(std::max<std::uint32_t>(count, 1)) * 8);
  Buffer* pair_bufs = nullptr;
  Buffer tmp[2];
  // The sort ping-pongs between two buffers: lend it pairs_ and pairs_tmp_.
  tmp[0] = std::move(pairs_);
  tmp[1] = std::move(pairs_tmp_);
  pair_bufs = tmp;
  const int key_bits = 32 + std::bit_width(objects ? objects - 1 : 0u);
  timers_.begin(Stage::query, 1);
  const int in = sort_.sort(pair_bufs, nullptr, count, key_bits, false);
  timers_.end(Stage::query, 1);
  // Keep the sorted pairs in pairs_ (the state pass and the read-back read them).
  pairs_ = std::move(tmp[in]);
  pairs_tmp_ = std::move(tmp[1 - in]);
  stats.pairs = count;
  return count;
}

void Broadphase::mark_colliding(std::uint32_t pairs) {
  timers_.begin(Stage::query, 2);  // stage 8's third part: the states
  pairs_.bind_storage(VISCD_BIND_PAIRS);
  frame_.states.bind_storage(VISCD_BIND_STATE);
  glProgramUniform1ui(state_.get(), state_.uniform("u_pairs"), pairs);
  state_.dispatch(pairs);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  timers_.end(Stage::query, 2);
}

std::vector<std::uint64_t> Broadphase::read_sorted_codes() {
  std::vector<std::uint32_t> raw(2 * static_cast<std::size_t>(last_n_));
  if (last_n_) glGetNamedBufferSubData(keys_[sorted_in_].get(), 0, 8 * static_cast<GLsizeiptr>(last_n_), raw.data());
  std::vector<std::uint64_t> codes(last_n_);
  for (std::size_t k = 0; k < last_n_; ++k) codes[k] = (std::uint64_t{raw[2 * k + 1]} << 32) | raw[2 * k];
  return codes;
}

std::vector<std::uint32_t> Broadphase::read_sorted_ids() {
  std::vector<std::uint32_t> ids(last_n_);
  if (last_n_) glGetNamedBufferSubData(values_[sorted_in_].get(), 0, 4 * static_cast<GLsizeiptr>(last_n_), ids.data());
  return ids;
}

void Broadphase::read_tree(detail::Lbvh& bvh, std::vector<detail::Aabb>& leaf_boxes) {
  const std::uint32_t n = last_n_;
  bvh.leaves = n;
  leaf_boxes.resize(n);
  static_assert(sizeof(detail::Aabb) == sizeof(shader::LeafBox) && sizeof(detail::BvhNode) == sizeof(shader::LbvhNode));
  if (n) glGetNamedBufferSubData(leaf_boxes_.get(), 0, 24 * static_cast<GLsizeiptr>(n), leaf_boxes.data());
  shader::FrameInfo info{};
  glGetNamedBufferSubData(frame_.info.get(), 0, sizeof info, &info);
  if (n >= 2) {
    bvh.nodes.resize(n - 1);
    bvh.parent.resize(n - 1);
    bvh.leaf_parent.resize(n);
    glGetNamedBufferSubData(nodes_.get(), 0, 64 * static_cast<GLsizeiptr>(n - 1), bvh.nodes.data());
    glGetNamedBufferSubData(parent_.get(), 0, 4 * static_cast<GLsizeiptr>(n - 1), bvh.parent.data());
    glGetNamedBufferSubData(parent_.get(), 4 * static_cast<GLintptr>(n - 1), 4 * static_cast<GLsizeiptr>(n),
                            bvh.leaf_parent.data());
  } else {
    bvh.nodes.clear();
    bvh.parent.clear();
    bvh.leaf_parent.assign(n, detail::kNoParent);
  }
  bvh.root_box = detail::Aabb{};
  if (n) {
    bvh.root_box.lo = {info.root_lo.x, info.root_lo.y, info.root_lo.z};
    bvh.root_box.hi = {info.root_hi.x, info.root_hi.y, info.root_hi.z};
  }
}

}  // namespace viscd::gl
