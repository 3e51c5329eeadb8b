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

bool Readback::ray(const Ray& ray, RayHit& hit) {
  read_active_spheres();
  return detail::brute_ray(query_active_, query_ids_, ray, hit);
}

void Readback::ray_all(const Ray& ray, std::vector<RayHit>& hits) {
  read_active_spheres();
  detail::brute_ray_all(query_active_, query_ids_, ray, hits);
}

void Readback::overlap(const Sphere& sphere, std::vector<std::uint32_t>& indices) {
  read_active_spheres();
  detail::brute_overlap(query_active_, query_ids_, sphere, indices);
}

void Readback::read_active_spheres() {
  if (query_copy_ready_) return;
  query_copy_ready_ = true;
  const std::uint32_t n = query_objects_;
  query_all_.resize(n);
  state_words_.resize(n);
  query_active_.clear();
  query_ids_.clear();
  if (n == 0 || !ctx_.make_current()) return;
  glGetNamedBufferSubData(frame_.spheres.get(), 0, 16 * static_cast<GLsizeiptr>(n), query_all_.data());
  glGetNamedBufferSubData(frame_.states.get(), 0, 4 * static_cast<GLsizeiptr>(n), state_words_.data());
  for (std::uint32_t k = 0; k < n; ++k) {
    if (state_words_[k] == VISCD_STATE_CULLED) continue;
    query_active_.push_back(query_all_[k]);
    query_ids_.push_back(k);
  }
}

}  // namespace viscd::gl
