// The gl backend's key sort (radix_sort.hpp): one-group local sort or LSD radix passes.
#include "gl/radix_sort.hpp"

#include <cstddef>

#include "gl/shaders/shared/layout.h"
#include "viscd/assert.hpp"

namespace viscd::gl {
Status RadixSort::init() {
  if (Status s = build_compute_programs({{&sort_local_, "sort_local.comp"},
                                         {&radix_hist_, "radix_hist.comp"},
                                         {&radix_scan_, "radix_scan.comp"},
                                         {&radix_scatter_, "radix_scatter.comp"}});
      !s)
    return s;
  VISCD_ASSERT(radix_scatter_.local_size() == 256 && radix_hist_.local_size() == 256 && radix_scan_.local_size() == 256,
               "radix sort needs one invocation per 8-bit digit");
  return {};
}

// Sort of uvec2 keys (and uint values) in keys[0]/values[0] by (key, value): up to
// VISCD_LOCAL_SORT keys in one work group (sort_local.comp), more by an LSD radix sort with 8-bit
// digits, ceil(key_bits / 8) passes (the pass count follows m), each three dispatches: tile
// histograms, one work group turning them into offsets, the scatter. The radix sort is stable
// and values start ascending, so both give the same order. The result lies where the passes
// leave it, keys[passes % 2], either way.
int RadixSort::sort(Buffer* keys, Buffer* values, std::uint32_t n, int key_bits, bool n_from_info) {
  if (n < 2) return 0;  // also with n_from_info: the GPU count is <= n, nothing to sort
  const int passes = (key_bits + 7) / 8;
  const int dst = passes % 2;
  for (const Program* p : {&sort_local_, &radix_hist_, &radix_scan_, &radix_scatter_}) {
    glProgramUniform1ui(p->get(), p->uniform("u_n"), n);
    glProgramUniform1ui(p->get(), p->uniform("u_n_from_info"), n_from_info ? 1u : 0u);
  }
  for (const Program* p : {&sort_local_, &radix_scatter_})
    glProgramUniform1ui(p->get(), p->uniform("u_has_values"), values ? 1u : 0u);
  frame_.info.bind_storage(VISCD_BIND_INFO);
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
      frame_.dispatch_indirect(p, offsetof(shader::DispatchArgs, sort_tiles));
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

}  // namespace viscd::gl
