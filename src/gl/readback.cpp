// The gl backend's read-backs (readback.hpp): pairs, states, pixels, and the queries' copy.
#include "gl/readback.hpp"

#include <utility>

#include "core/brute_queries.hpp"
#include "gl/shaders/shared/layout.h"

namespace viscd::gl {

void Readback::begin_frame(std::uint32_t objects, std::uint32_t moving, std::span<const std::uint32_t> slots) {
  query_copy_ready_ = false;
  query_objects_ = objects;
  query_moving_ = moving;
  query_boxes_ = frame_.has_boxes;
  static_ids_.resize(slots.size());
  for (std::size_t s = 0; s < slots.size(); ++s) static_ids_[s] = static_index(slots[s]);
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
  read_active_objects();
  if (query_boxes_) return {detail::Shapes(query_active_boxes_), query_ids_, query_active_filters_};
  return {detail::Shapes(query_active_), query_ids_, query_active_filters_};
}

void Readback::read_active_objects() {
  if (query_copy_ready_) return;
  query_copy_ready_ = true;
  const std::uint32_t n = query_objects_, moving = query_moving_;
  // Filters stay on the GPU (uploaded for the pair stages) and come back only with the rest.
  const bool filters = frame_.has_filters && n > 0;
  query_all_.resize(query_boxes_ ? 0 : n);
  query_all_boxes_.resize(query_boxes_ ? n : 0);
  state_words_.resize(moving);
  query_all_filters_.resize(filters ? n : 0);
  query_active_.clear();
  query_active_boxes_.clear();
  query_ids_.clear();
  query_active_filters_.clear();
  if (n == 0 || !ctx_.make_current()) return;
  // Room for every object, so that no allocation follows the active count as it changes.
  if (query_boxes_)
    query_active_boxes_.reserve(n);
  else
    query_active_.reserve(n);
  query_ids_.reserve(n);
  if (filters) query_active_filters_.reserve(n);
  if (query_boxes_)
    glGetNamedBufferSubData(frame_.boxes.get(), 0, 24 * static_cast<GLsizeiptr>(n), query_all_boxes_.data());
  else
    glGetNamedBufferSubData(frame_.spheres.get(), 0, 16 * static_cast<GLsizeiptr>(n), query_all_.data());
  if (moving) glGetNamedBufferSubData(frame_.states.get(), 0, 4 * static_cast<GLsizeiptr>(moving), state_words_.data());
  if (filters)
    glGetNamedBufferSubData(frame_.filters.get(), 0, 8 * static_cast<GLsizeiptr>(n), query_all_filters_.data());
  // Moving objects unless culled, then every static object (never culled): ids ascend.
  for (std::uint32_t k = 0; k < n; ++k) {
    if (k < moving && state_words_[k] == VISCD_STATE_CULLED) continue;
    if (query_boxes_)
      query_active_boxes_.push_back(query_all_boxes_[k]);
    else
      query_active_.push_back(query_all_[k]);
    query_ids_.push_back(k < moving ? k : static_ids_[k - moving]);
    if (filters) query_active_filters_.push_back(query_all_filters_[k]);
  }
}

}  // namespace viscd::gl
