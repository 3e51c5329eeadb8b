// Stage 3 of the gl backend (cull.hpp): cull, filters, scan, compaction, dispatch sizes.
#include "gl/cull.hpp"

#include <cstddef>

#include "gl/shaders/shared/layout.h"
#include "viscd/assert.hpp"

namespace viscd::gl {
Status Culling::init() {
  if (Status s = build_compute_programs({{&scan_local_, "scan_local.comp"},
                                         {&scan_blocks_, "scan_blocks.comp"},
                                         {&scan_add_, "scan_add.comp"},
                                         {&cull_, "cull.comp"},
                                         {&pairable_, "pairable.comp"},
                                         {&compact_, "compact.comp"},
                                         {&dispatch_args_, "dispatch_args.comp"}});
      !s)
    return s;
  VISCD_ASSERT(scan_local_.local_size() * VISCD_SCAN_PER_THREAD == VISCD_SCAN_BLOCK, "scan block size");
  return {};
}

void Culling::reserve(std::uint32_t objects) {
  for (Buffer* b : {&flags_, &scan_out_}) b->reserve(4 * static_cast<GLsizeiptr>(objects));
}

std::uint64_t Culling::buffer_bytes() const {
  std::uint64_t b = 0;
  for (const Buffer* buf : {&flags_, &scan_out_, &block_sums_}) b += static_cast<std::uint64_t>(buf->size());
  return b;
}

void Culling::cull(std::uint32_t objects, std::uint32_t moving) {
  timers_.begin(Stage::cull);
  frame_.counts.bind_storage(VISCD_BIND_COUNTS);
  frame_.pixels.bind_storage(VISCD_BIND_PIXELS);
  flags_.bind_storage(VISCD_BIND_FLAGS);
  frame_.states.bind_storage(VISCD_BIND_STATE);
  frame_.info.bind_storage(VISCD_BIND_INFO);
  if (frame_.has_filters) frame_.filters.bind_storage(VISCD_BIND_FILTERS);
  if (frame_.has_always) frame_.always.bind_storage(VISCD_BIND_ALWAYS);
  const GLuint p = cull_.get();
  glProgramUniform1ui(p, cull_.uniform("u_n"), objects);
  glProgramUniform1ui(p, cull_.uniform("u_moving"), moving);
  glProgramUniform1ui(p, cull_.uniform("u_has_counts"), frame_.has_pixels ? 1u : 0u);
  glProgramUniform1ui(p, cull_.uniform("u_culling"), config_.culling ? 1u : 0u);
  glProgramUniform1ui(p, cull_.uniform("u_has_filters"), frame_.has_filters ? 1u : 0u);
  glProgramUniform1ui(p, cull_.uniform("u_has_always"), frame_.has_always ? 1u : 0u);
  glProgramUniform1d(p, cull_.uniform("u_scale"), frame_.pixel_scale);
  glProgramUniform1d(p, cull_.uniform("u_lambda"), static_cast<double>(config_.lambda));
  cull_.dispatch(objects);
  barrier();
  if (frame_.has_filters) {
    glProgramUniform1ui(pairable_.get(), pairable_.uniform("u_n"), objects);
    pairable_.dispatch(objects);
    barrier();
  }
  scan(flags_.get(), scan_out_.get(), objects);
  // scan() leaves the total (the active count) in block_sums_[blocks]; copy it on the GPU.
  const std::uint32_t blocks = (objects + VISCD_SCAN_BLOCK - 1) / VISCD_SCAN_BLOCK;
  glCopyNamedBufferSubData(block_sums_.get(), frame_.info.get(), 4 * static_cast<GLintptr>(blocks),
                           offsetof(shader::FrameInfo, active_count), 4);
  flags_.bind_storage(VISCD_BIND_FLAGS);
  scan_out_.bind_storage(VISCD_BIND_SCAN_OUT);
  frame_.active.bind_storage(VISCD_BIND_ACTIVE);
  glProgramUniform1ui(compact_.get(), compact_.uniform("u_n"), objects);
  compact_.dispatch(objects);
  barrier();
  write_dispatch_args();
  timers_.end(Stage::cull);
}

// Exclusive scan of n uints from `in` into `out` (three dispatches, reduce-then-scan). Leaves the
// total in block_sums_[ceil(n / VISCD_SCAN_BLOCK)].
void Culling::scan(GLuint in, GLuint out, std::uint32_t n) {
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

void Culling::write_dispatch_args() {
  frame_.info.bind_storage(VISCD_BIND_INFO);
  frame_.dispatch.bind_storage(VISCD_BIND_DISPATCH);
  glUseProgram(dispatch_args_.get());
  glDispatchCompute(1, 1, 1);
  barrier();  // GL_COMMAND_BARRIER_BIT among them: the indirect dispatches see the counts
}

}  // namespace viscd::gl
