// For tests only (test_access.hpp): GlInspector's calls into a GlDetector's parts.
#include "gl/test_access.hpp"

#include <algorithm>

#include "core/frame_rules.hpp"
#include "core/morton.hpp"
#include "viscd/assert.hpp"
#include "viscd/detector.hpp"

namespace viscd::gl {

void GlInspector::set_options(const GlOptions& options) { d_->options_ = options; }

const std::string& GlInspector::device() const { return d_->ctx_->description(); }

std::uint64_t GlInspector::mid_frame_waits() const { return d_->layout_.mid_frame_waits(); }

std::uint32_t GlInspector::pair_capacity() const { return d_->broadphase_.pair_capacity(); }

Status GlInspector::run_broadphase(const detail::Shapes& objects, std::span<const std::uint32_t> active, int bits,
                                   std::vector<Pair>& pairs, FrameStats& stats, std::uint32_t static_from) {
  VISCD_ASSERT(bits == 16 || bits == 32 || bits == 64, "Morton width must be 16, 32 or 64");
  if (Status s = objects.is_box() ? validate_boxes(objects.boxes) : validate_spheres(objects.spheres); !s) return s;
  GlDetector& d = *d_;
  if (!d.ctx_->make_current())
    return Status::failure(ErrorKind::backend_failure, "OpenGL: cannot make the detector's context current");
  FrameData& frame = d.frame_;
  const auto total = static_cast<std::uint32_t>(objects.size());
  frame.upload_objects(objects, std::min(static_from, total));
  frame.has_filters = false;
  d.readback_.begin_frame(0, 0, {});  // a stage test, not a frame: queries see no objects
  const auto n = static_cast<std::uint32_t>(active.size());
  frame.active.reserve(4 * static_cast<GLsizeiptr>(n));
  frame.states.reserve(4 * static_cast<GLsizeiptr>(total));
  if (n) glNamedBufferSubData(frame.active.get(), 0, 4 * static_cast<GLsizeiptr>(n), active.data());
  shader::FrameInfo zero_info{};
  zero_info.active_count = n;  // the shaders read n from FrameInfo
  glNamedBufferSubData(frame.info.get(), 0, sizeof zero_info, &zero_info);
  d.culling_.write_dispatch_args();
  const detail::ActiveExtent e = detail::extent_of(objects, active, 0, active.size());
  const detail::MortonLayout layout = detail::make_layout(d.config_.layout, bits, e.bounds, e.mean_diameter());
  stats.bits = bits;
  stats.layout = layout.info();
  stats.active = n;
  stats.objects = total;
  const auto count = d.broadphase_.run(n, total, static_from, layout, e.bounds, stats);
  if (!count) return count.status();
  d.readback_.read_pairs(d.broadphase_.pairs(), count.value(), pairs);
  return d.gl_errors("run_broadphase()");
}

std::vector<std::uint64_t> GlInspector::read_sorted_codes() {
  (void)d_->ctx_->make_current();
  return d_->broadphase_.read_sorted_codes();
}

std::vector<std::uint32_t> GlInspector::read_sorted_ids() {
  (void)d_->ctx_->make_current();
  return d_->broadphase_.read_sorted_ids();
}

void GlInspector::read_tree(detail::Lbvh& bvh, std::vector<detail::Aabb>& leaf_boxes) {
  (void)d_->ctx_->make_current();
  d_->broadphase_.read_tree(bvh, leaf_boxes);
}

std::vector<std::uint32_t> GlInspector::read_id_map() {
  (void)d_->ctx_->make_current();
  return d_->visibility_.read_id_map();
}

Result<std::vector<std::uint32_t>> GlInspector::count_id_map(std::span<const std::uint32_t> ids, int width, int height,
                                                             std::uint32_t objects) {
  using R = Result<std::vector<std::uint32_t>>;
  if (!d_->ctx_->make_current())
    return R::failure(ErrorKind::backend_failure, "OpenGL: cannot make the detector's context current");
  R counts = d_->visibility_.count_id_map(ids, width, height, objects);
  if (!counts) return counts;
  if (Status s = d_->gl_errors("count_id_map()"); !s) return R::failure(s);
  return counts;
}

}  // namespace viscd::gl
