// Stages 5-8 of the gl backend: Morton codes, radix sort, Karras build, fit, query, pair sort.
#include <bit>
#include <cmath>
#include <cstring>

#include "core/frame_rules.hpp"
#include "core/stopwatch.hpp"
#include "gl/gl_detector.hpp"

namespace viscd::gl {
namespace {

void barrier() { glMemoryBarrier(GL_ALL_BARRIER_BITS); }

}  // namespace

// Exclusive scan of n uints from `in` into `out` (three dispatches, reduce-then-scan). Leaves the
// total in block_sums_[ceil(n / VISCD_SCAN_BLOCK)].
void GlDetector::scan(GLuint in, GLuint out, std::uint32_t n) {
  const std::uint32_t blocks = (n + VISCD_SCAN_BLOCK - 1) / VISCD_SCAN_BLOCK;
  block_sums_.reserve(4 * (static_cast<GLsizeiptr>(blocks) + 1));
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, VISCD_BIND_SCAN_IN, in);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, VISCD_BIND_SCAN_OUT, out);
  block_sums_.bind_storage(VISCD_BIND_SCAN_BLOCKS);
  if (blocks) {
    glProgramUniform1ui(scan_local_.get(), scan_local_.uniform("u_n"), n);
    glUseProgram(scan_local_.get());
    glDispatchCompute(blocks, 1, 1);
    barrier();
  }
  glProgramUniform1ui(scan_blocks_.get(), scan_blocks_.uniform("u_count"), blocks);
  glUseProgram(scan_blocks_.get());
  glDispatchCompute(1, 1, 1);
  barrier();
  if (blocks > 1) {
    glProgramUniform1ui(scan_add_.get(), scan_add_.uniform("u_n"), n);
    scan_add_.dispatch(n);
    barrier();
  }
}

void GlDetector::write_dispatch_args() {
  info_.bind_storage(VISCD_BIND_INFO);
  dispatch_.bind_storage(VISCD_BIND_DISPATCH);
  glUseProgram(dispatch_args_.get());
  glDispatchCompute(1, 1, 1);
  barrier();  // GL_COMMAND_BARRIER_BIT among them: the indirect dispatches see the counts
}

void GlDetector::dispatch_indirect(const Program& p, GLintptr offset) const {
  glUseProgram(p.get());
  glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, dispatch_.get());
  glDispatchComputeIndirect(offset);
}

// Sort of uvec2 keys (and uint values) in keys[0]/values[0] by (key, value): up to
// VISCD_LOCAL_SORT keys in one work group (sort_local.comp), more by an LSD radix sort with 8-bit
// digits, ceil(key_bits / 8) passes (the pass count follows m), each three dispatches: tile
// histograms, one work group turning them into offsets, the scatter. The radix sort is stable
// and values start ascending, so both give the same order. The result lies where the passes
// leave it, keys[passes % 2], either way.
int GlDetector::radix_sort(Buffer* keys, Buffer* values, std::uint32_t n, int key_bits, bool n_from_info) {
  if (n < 2) return 0;  // also with n_from_info: the GPU count is <= n, nothing to sort
  const int passes = (key_bits + 7) / 8;
  const int dst = passes % 2;
  for (const Program* p : {&sort_local_, &radix_hist_, &radix_scan_, &radix_scatter_}) {
    glProgramUniform1ui(p->get(), p->uniform("u_n"), n);
    glProgramUniform1ui(p->get(), p->uniform("u_n_from_info"), n_from_info ? 1u : 0u);
  }
  for (const Program* p : {&sort_local_, &radix_scatter_})
    glProgramUniform1ui(p->get(), p->uniform("u_has_values"), values ? 1u : 0u);
  info_.bind_storage(VISCD_BIND_INFO);
  // Few keys (the count on the GPU is at most n): the local sort alone. Otherwise, with the
  // count on the GPU, the local sort runs for a small count and the radix passes (0 tiles from
  // DispatchArgs) for a large one; with the count on the host, only the radix passes.
  if (n <= VISCD_LOCAL_SORT || n_from_info) {
    keys[0].bind_storage(VISCD_BIND_KEYS_IN);
    keys[dst].bind_storage(VISCD_BIND_KEYS_OUT);
    if (values) {
      values[0].bind_storage(VISCD_BIND_VALUES_IN);
      values[dst].bind_storage(VISCD_BIND_VALUES_OUT);
    }
    glUseProgram(sort_local_.get());
    glDispatchCompute(1, 1, 1);
    barrier();
    if (n <= VISCD_LOCAL_SORT) return dst;
  }
  const std::uint32_t tiles = (n + VISCD_SORT_TILE - 1) / VISCD_SORT_TILE;
  hist_.reserve(static_cast<GLsizeiptr>(4) * 256 * tiles);
  int src = 0;
  hist_.bind_storage(VISCD_BIND_SCAN_IN);
  const auto over_tiles = [&](const Program& p) {
    if (n_from_info) {
      dispatch_indirect(p, offsetof(shader::DispatchArgs, sort_tiles));
    } else {
      glUseProgram(p.get());
      glDispatchCompute(tiles, 1, 1);
    }
    barrier();
  };
  for (int pass = 0; pass < passes; ++pass) {
    const auto shift = static_cast<GLuint>(8 * pass);
    keys[src].bind_storage(VISCD_BIND_KEYS_IN);
    keys[1 - src].bind_storage(VISCD_BIND_KEYS_OUT);
    if (values) {
      values[src].bind_storage(VISCD_BIND_VALUES_IN);
      values[1 - src].bind_storage(VISCD_BIND_VALUES_OUT);
    }
    glProgramUniform1ui(radix_hist_.get(), radix_hist_.uniform("u_shift"), shift);
    glProgramUniform1ui(radix_scatter_.get(), radix_scatter_.uniform("u_shift"), shift);
    over_tiles(radix_hist_);
    glUseProgram(radix_scan_.get());
    glDispatchCompute(1, 1, 1);
    barrier();
    over_tiles(radix_scatter_);
    src = 1 - src;
  }
  VISCD_ASSERT(src == dst, "the passes end where the local sort writes");
  return src;
}

void GlDetector::reserve_broadphase(std::uint32_t n) {
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
// in sync mode, and in run_broadphase, it is n itself.
Status GlDetector::broadphase(std::uint32_t n_bound, std::uint32_t objects, const detail::MortonLayout& layout,
                              const detail::Aabb& bounds, std::vector<Pair>& pairs, FrameStats& stats) {
  const std::uint32_t n = n_bound;
  reserve_broadphase(n);
  constexpr GLintptr per_object = offsetof(shader::DispatchArgs, per_object);
  info_.bind_storage(VISCD_BIND_INFO);

  // Stage 5: codes, on the shared quantisation grid (core/morton.hpp), so they equal the cpu
  // backend's bit for bit.
  stage_begin(Stage::codes);
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
    spheres_.bind_storage(VISCD_BIND_SPHERES);
    active_.bind_storage(VISCD_BIND_ACTIVE);
    keys_[0].bind_storage(VISCD_BIND_KEYS_OUT);
    values_[0].bind_storage(VISCD_BIND_VALUES_OUT);
    dispatch_indirect(morton_, per_object);
    barrier();
  }
  stage_end(Stage::codes);

  // Stage 6: sort (key, object index); values start ascending, the sort is stable.
  stage_begin(Stage::sort);
  sorted_in_ = radix_sort(keys_, values_, n, layout.bits, true);
  stage_end(Stage::sort);

  // Stage 7: build, then fit.
  stage_begin(Stage::build);
  keys_[sorted_in_].bind_storage(VISCD_BIND_KEYS_IN);
  nodes_.bind_storage(VISCD_BIND_NODES);
  parent_.bind_storage(VISCD_BIND_PARENT);
  arrivals_.bind_storage(VISCD_BIND_ARRIVALS);  // zeroed by the build, one per internal node
  glProgramUniform1i(build_.get(), build_.uniform("u_bits"), layout.bits);
  dispatch_indirect(build_, offsetof(shader::DispatchArgs, per_node));
  barrier();
  stage_end(Stage::build);
  stage_begin(Stage::fit);
  spheres_.bind_storage(VISCD_BIND_SPHERES);
  values_[sorted_in_].bind_storage(VISCD_BIND_VALUES_IN);
  sorted_.bind_storage(VISCD_BIND_SORTED);
  leaf_boxes_.bind_storage(VISCD_BIND_LEAF_BOXES);
  arrivals_.bind_storage(VISCD_BIND_ARRIVALS);
  info_.bind_storage(VISCD_BIND_INFO);
  dispatch_indirect(fit_, per_object);
  barrier();
  stage_end(Stage::fit);

  // Stage 8: query; on overflow grow the buffer to the exact count and run it again. Its GPU
  // time is three intervals (stage_begin parts): the traversal (the last attempt), the pair
  // sort, and the states (mark_colliding); the host waits between them are not GPU work.
  // The previous frame's pair sort may have left its smaller buffer (sized for that frame's
  // count) as pairs_: make sure pairs_ holds the pair_capacity_ pairs the query may write.
  pairs_.reserve(static_cast<GLsizeiptr>(pair_capacity_) * 8);
  std::uint32_t count = 0;
  for (int attempt = 0;; ++attempt) {
    VISCD_ASSERT(attempt < 2, "the pair count is exact, one re-run suffices");
    const GLuint zero = 0;
    glNamedBufferSubData(info_.get(), offsetof(shader::FrameInfo, pair_count), 4, &zero);
    pairs_.bind_storage(VISCD_BIND_PAIRS);
    glProgramUniform1ui(query_.get(), query_.uniform("u_capacity"), pair_capacity_);
    glProgramUniform1ui(query_.get(), query_.uniform("u_has_filters"), has_filters_ ? 1u : 0u);
    if (has_filters_) filters_.bind_storage(VISCD_BIND_FILTERS);
    stage_begin(Stage::query, 0);
    dispatch_indirect(query_, per_object);
    barrier();
    stage_end(Stage::query, 0);
    // The frame's one wait (both modes): the whole FrameInfo, i.e. the pair count and this
    // frame's n, bounds, diameter sum and pixel total (the next frame's layout inputs).
    glGetNamedBufferSubData(info_.get(), 0, sizeof frame_info_, &frame_info_);
    count = frame_info_.pair_count;
    last_n_ = frame_info_.active_count;
    if (Status s = detail::check_pair_cap(count, config_.pair_memory_cap); !s) return s;
    if (count <= pair_capacity_) break;
    // A pair count beyond 2^32 - 1 would wrap the counter; N < 2^29 with our spheres cannot
    // fill 2^32 pairs on any machine this runs on, and the cap check above catches it first.
    pair_capacity_ = count;
    pairs_.reserve(static_cast<GLsizeiptr>(pair_capacity_) * 8);
  }
  // Sort the pairs as 64-bit keys (i << 32 | j): x = j, y = i; i, j < objects.
  pairs_tmp_.reserve(static_cast<GLsizeiptr>(std::max<std::uint32_t>(count, 1)) * 8);
  Buffer* pair_bufs = nullptr;
  Buffer tmp[2];
  // radix_sort ping-pongs between two buffers: lend it pairs_ and pairs_tmp_.
  tmp[0] = std::move(pairs_);
  tmp[1] = std::move(pairs_tmp_);
  pair_bufs = tmp;
  const int key_bits = 32 + std::bit_width(objects ? objects - 1 : 0u);
  stage_begin(Stage::query, 1);
  const int in = radix_sort(pair_bufs, nullptr, count, key_bits, false);
  stage_end(Stage::query, 1);
  // Keep the sorted pairs in pairs_ (the state pass reads them).
  pairs_ = std::move(tmp[in]);
  pairs_tmp_ = std::move(tmp[1 - in]);
  pairs.resize(count);
  if (count) {
    glGetNamedBufferSubData(pairs_.get(), 0, static_cast<GLsizeiptr>(count) * 8, pairs.data());
    for (Pair& p : pairs) std::swap(p.i, p.j);  // stored (x = j, y = i)
  }
  stats.pairs = count;
  return {};
}

Status GlDetector::run_broadphase(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, int bits,
                                  std::vector<Pair>& pairs, FrameStats& stats) {
  VISCD_ASSERT(bits == 16 || bits == 32 || bits == 64, "Morton width must be 16, 32 or 64");
  if (Status s = validate_spheres(spheres); !s) return s;
  if (!ctx_->make_current())
    return Status::failure(ErrorKind::backend_failure, "OpenGL: cannot make the detector's context current");
  upload_spheres(spheres);
  has_filters_ = false;
  query_copy_ready_ = false;  // a stage test, not a frame: queries see no objects
  query_objects_ = 0;
  const auto n = static_cast<std::uint32_t>(active.size());
  active_.reserve(4 * static_cast<GLsizeiptr>(n));
  states_.reserve(4 * static_cast<GLsizeiptr>(spheres.size()));
  if (n) glNamedBufferSubData(active_.get(), 0, 4 * static_cast<GLsizeiptr>(n), active.data());
  shader::FrameInfo zero_info{};
  zero_info.active_count = n;  // the shaders read n from FrameInfo
  glNamedBufferSubData(info_.get(), 0, sizeof zero_info, &zero_info);
  write_dispatch_args();
  const detail::ActiveExtent e = detail::extent_of(spheres, active, 0, active.size());
  const detail::MortonLayout layout = detail::make_layout(config_.layout, bits, e.bounds, e.mean_diameter());
  stats.bits = bits;
  stats.layout = layout.info();
  stats.active = n;
  stats.objects = static_cast<std::uint32_t>(spheres.size());
  if (Status s = broadphase(n, static_cast<std::uint32_t>(spheres.size()), layout, e.bounds, pairs, stats); !s)
    return s;
  return gl_errors("run_broadphase()");
}

std::vector<std::uint64_t> GlDetector::read_sorted_codes() {
  (void)ctx_->make_current();
  std::vector<std::uint32_t> raw(2 * static_cast<std::size_t>(last_n_));
  if (last_n_) glGetNamedBufferSubData(keys_[sorted_in_].get(), 0, 8 * static_cast<GLsizeiptr>(last_n_), raw.data());
  std::vector<std::uint64_t> codes(last_n_);
  for (std::size_t k = 0; k < last_n_; ++k) codes[k] = (std::uint64_t{raw[2 * k + 1]} << 32) | raw[2 * k];
  return codes;
}

std::vector<std::uint32_t> GlDetector::read_sorted_ids() {
  (void)ctx_->make_current();
  std::vector<std::uint32_t> ids(last_n_);
  if (last_n_) glGetNamedBufferSubData(values_[sorted_in_].get(), 0, 4 * static_cast<GLsizeiptr>(last_n_), ids.data());
  return ids;
}

void GlDetector::read_tree(detail::Lbvh& bvh, std::vector<detail::Aabb>& leaf_boxes) {
  (void)ctx_->make_current();
  const std::uint32_t n = last_n_;
  bvh.leaves = n;
  leaf_boxes.resize(n);
  static_assert(sizeof(detail::Aabb) == sizeof(shader::LeafBox) && sizeof(detail::BvhNode) == sizeof(shader::LbvhNode));
  if (n) glGetNamedBufferSubData(leaf_boxes_.get(), 0, 24 * static_cast<GLsizeiptr>(n), leaf_boxes.data());
  shader::FrameInfo info{};
  glGetNamedBufferSubData(info_.get(), 0, sizeof info, &info);
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
