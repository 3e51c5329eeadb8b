// The gl backend's read-backs (readback.hpp): pairs, states, pixels, and the queries' copy.
#include "gl/readback.hpp"

#include <utility>

#include "core/brute_queries.hpp"
#include "gl/shaders/shared/layout.h"

namespace viscd::gl {

void Readback::begin_frame(std::uint32_t objects) {
  query_copy_ready_ = false;
  query_objects_ = objects;
}

void Readback::read_pairs(const Buffer& sorted, std::uint32_t count, std::vector<Pair>& pairs) {
  pairs.resize(count);
  if (count) {
    glGetNamedBufferSubData(sorted.get(), 0, static_cast<GLsizeiptr>(count) * 8, pairs.data());
    for (Pair& p : pairs) std::swap(p.i, p.j);  // stored (x = j, y = i)
  }
}

void Readback::read_states_and_pixels(std::uint32_t objects, bool has_pixels, FrameResult& out) {
  state_words_.resize(objects);
  if (objects)
    glGetNamedBufferSubData(frame_.states.get(), 0, 4 * static_cast<GLsizeiptr>(objects), state_words_.data());
  out.state.resize(objects);
  for (std::uint32_t k = 0; k < objects; ++k) out.state[k] = static_cast<ObjectState>(state_words_[k]);
  if (has_pixels) {
    out.pixels.resize(objects);
    if (objects)
      glGetNamedBufferSubData(frame_.pixels.get(), 0, 4 * static_cast<GLsizeiptr>(objects), out.pixels.data());
  } else {
    out.pixels.clear();
  }
}

detail::QueryObjects Readback::query_objects() {
  read_active_spheres();
  return {query_active_, query_ids_, query_active_filters_};
}

void Readback::read_active_spheres() {
  if (query_copy_ready_) return;
  query_copy_ready_ = true;
  const std::uint32_t n = query_objects_;
  // Filters stay on the GPU (uploaded for the pair stages) and come back only with the rest.
  const bool filters = frame_.has_filters && n > 0;
  query_all_.resize(n);
  state_words_.resize(n);
  query_all_filters_.resize(filters ? n : 0);
  query_active_.clear();
  query_ids_.clear();
  query_active_filters_.clear();
  if (n == 0 || !ctx_.make_current()) return;
  glGetNamedBufferSubData(frame_.spheres.get(), 0, 16 * static_cast<GLsizeiptr>(n), query_all_.data());
  glGetNamedBufferSubData(frame_.states.get(), 0, 4 * static_cast<GLsizeiptr>(n), state_words_.data());
  if (filters)
    glGetNamedBufferSubData(frame_.filters.get(), 0, 8 * static_cast<GLsizeiptr>(n), query_all_filters_.data());
  for (std::uint32_t k = 0; k < n; ++k) {
    if (state_words_[k] == VISCD_STATE_CULLED) continue;
    query_active_.push_back(query_all_[k]);
    query_ids_.push_back(k);
    if (filters) query_active_filters_.push_back(query_all_filters_[k]);
  }
}

}  // namespace viscd::gl
