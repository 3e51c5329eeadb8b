#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <new>
#include <numeric>
#include <string>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/backend.hpp"
#include "core/brute_queries.hpp"
#include "core/frame_rules.hpp"
#include "core/geometry.hpp"
#include "viscd/assert.hpp"
#include "viscd/cuda.hpp"
#include "viscd/detector.hpp"
#include "viscd/gl.hpp"

namespace viscd {

#ifndef VISCD_HAVE_GL
// Without the gl backend (VISCD_ENABLE_GL=OFF) its entry points exist and say so; src/gl defines
// them otherwise.
Result<std::unique_ptr<Detector>> make_gl_detector(const Config&, const GlOptions&) {
  return Result<std::unique_ptr<Detector>>::failure(ErrorKind::unsupported_input,
                                                    "backend 'gl' is not built in (configure with VISCD_ENABLE_GL=ON)");
}

Result<std::string> gl_device() {
  return Result<std::string>::failure(ErrorKind::unsupported_input,
                                      "viscd was built without the gl backend (VISCD_ENABLE_GL=OFF)");
}

Result<unsigned> make_gl_id_texture(int, int) {
  return Result<unsigned>::failure(ErrorKind::unsupported_input,
                                   "viscd was built without the gl backend (VISCD_ENABLE_GL=OFF)");
}
#endif

#ifndef VISCD_HAVE_CUDA
// Without the cuda backend (no nvcc found, or VISCD_ENABLE_CUDA=OFF) its entry points say so;
// src/cuda defines them otherwise.
Result<std::unique_ptr<Detector>> make_cuda_detector(const Config&) {
  return Result<std::unique_ptr<Detector>>::failure(
      ErrorKind::unsupported_input,
      "backend 'cuda' is not built in (configure with VISCD_ENABLE_CUDA=ON where nvcc is installed)");
}

Result<std::string> cuda_device() {
  return Result<std::string>::failure(ErrorKind::unsupported_input,
                                      "viscd was built without the cuda backend (VISCD_ENABLE_CUDA=OFF or no nvcc)");
}

Result<std::unique_ptr<CudaBroadphase>> make_cuda_broadphase(const Config&) {
  return Result<std::unique_ptr<CudaBroadphase>>::failure(
      ErrorKind::unsupported_input, "viscd was built without the cuda backend (VISCD_ENABLE_CUDA=OFF or no nvcc)");
}
#endif

bool is_software_renderer(std::string_view device) {
  for (std::string_view soft : {"llvmpipe", "softpipe", "swrast", "lavapipe", "Software Rasterizer"})
    if (device.find(soft) != std::string_view::npos) return true;
  return false;
}

Result<std::unique_ptr<Detector>> make_detector(std::string_view backend, const Config& config) {
  if (backend == "reference") return make_reference_detector(config);
  if (backend == "cpu") return make_cpu_detector(config);
  if (backend == "gl") return make_gl_detector(config);
  if (backend == "cuda") return make_cuda_detector(config);
  return Result<std::unique_ptr<Detector>>::failure(
      ErrorKind::invalid_input, "unknown backend '" + std::string(backend) + "': expected reference, cpu, gl or cuda");
}

bool spheres_overlap(const Sphere& a, const Sphere& b) { return detail::overlap_exact(a, b); }

bool ray_hits_sphere(const Ray& ray, const Sphere& sphere, float& t) {
  return detail::ray_sphere(ray.origin, ray.dir, ray.max_t, sphere, t);
}

namespace {
bool valid_sphere(const Sphere& s) { return validate_spheres(std::span<const Sphere>(&s, 1)).ok(); }

// A box every query takes: finite bounds, min <= max on every axis (false for NaN too).
bool valid_box(const Box& b) {
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(b.min[k]) || !std::isfinite(b.max[k]) || !(b.min[k] <= b.max[k])) return false;
  return true;
}
}  // namespace

bool sphere_overlaps_box(const Sphere& sphere, const Box& box) {
  return valid_sphere(sphere) && valid_box(box) && detail::sphere_box_exact(sphere, box.min, box.max);
}

bool boxes_overlap(const Box& a, const Box& b) { return detail::box_overlap_exact(a, b); }

bool ray_hits_box(const Ray& ray, const Box& box, float& t) {
  return validate_boxes({&box, 1}).ok() && detail::ray_box_exact(ray.origin, ray.dir, ray.max_t, box, t);
}

// ---- Detector: the frame around run_frame(), contact events, queries ----

namespace {

template <class T>
void reserve_with_headroom(std::vector<T>& v, std::size_t n) {
  if (v.capacity() < n) v.reserve(n + n / 2);
}

// began = now \ before, ended = before \ now, both sorted: one merge of the two sorted lists.
// The outputs only grow to the largest count seen, so a steady state allocates nothing.
void pair_differences(const std::vector<Pair>& before, const std::vector<Pair>& now, std::vector<Pair>& began,
                      std::vector<Pair>& ended) {
  began.clear();
  ended.clear();
  // Room for the most each can hold, with headroom as the pair count drifts.
  reserve_with_headroom(began, now.size());
  reserve_with_headroom(ended, before.size());
  auto b = before.begin(), n = now.begin();
  while (b != before.end() && n != now.end()) {
    if (*b < *n) {
      ended.push_back(*b++);
    } else if (*n < *b) {
      began.push_back(*n++);
    } else {
      ++b, ++n;
    }
  }
  ended.insert(ended.end(), b, before.end());
  began.insert(began.end(), n, now.end());
}

// The checks every query makes on its ray.
bool valid_ray(const Ray& r) {
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(r.origin[k]) || !std::isfinite(r.dir[k])) return false;
  const bool moves = r.dir[0] != 0 || r.dir[1] != 0 || r.dir[2] != 0;
  return moves && r.max_t >= 0;  // false for a NaN max_t too
}

// Hits sort by (t, index).
bool hit_before(const RayHit& a, const RayHit& b) { return a.t < b.t || (a.t == b.t && a.index < b.index); }

}  // namespace

namespace detail {

namespace {
Filter filter_of(const QueryObjects& o, std::size_t k) { return o.filters.empty() ? Filter{} : o.filters[k]; }
}  // namespace

bool brute_ray(const QueryObjects& o, const Ray& ray, const Filter* filter, RayHit& hit) {
  bool found = false;
  for (std::size_t k = 0; k < o.shapes.size(); ++k) {
    float t = 0;
    if (!query_passes(filter, filter_of(o, k)) || !o.shapes.ray_hit(k, ray, t)) continue;
    const RayHit h{o.ids[k], t};
    if (!found || hit_before(h, hit)) hit = h;
    found = true;
  }
  return found;
}

void brute_ray_all(const QueryObjects& o, const Ray& ray, const Filter* filter, std::vector<RayHit>& hits) {
  for (std::size_t k = 0; k < o.shapes.size(); ++k) {
    float t = 0;
    if (query_passes(filter, filter_of(o, k)) && o.shapes.ray_hit(k, ray, t)) hits.push_back({o.ids[k], t});
  }
}

void brute_ray_visit(const QueryObjects& o, const Ray& ray, const Filter* filter, RayVisitor& visitor) {
  Ray r = ray;  // r.max_t is the current max t
  for (std::size_t k = 0; k < o.shapes.size(); ++k) {
    float t = 0;
    if (!query_passes(filter, filter_of(o, k)) || !o.shapes.ray_hit(k, r, t)) continue;
    if (!apply_ray_answer(visitor.on_hit({o.ids[k], t}), r.max_t)) return;
  }
}

void brute_overlap(const QueryObjects& o, const Sphere& sphere, const Filter* filter,
                   std::vector<std::uint32_t>& indices) {
  for (std::size_t k = 0; k < o.shapes.size(); ++k)
    if (query_passes(filter, filter_of(o, k)) && o.shapes.meets_sphere(k, sphere)) indices.push_back(o.ids[k]);
}

void brute_overlap_box(const QueryObjects& o, const Box& box, const Filter* filter,
                       std::vector<std::uint32_t>& indices) {
  for (std::size_t k = 0; k < o.shapes.size(); ++k)
    if (query_passes(filter, filter_of(o, k)) && o.shapes.meets_box(k, box)) indices.push_back(o.ids[k]);
}

void brute_overlap_visit(const QueryObjects& o, const Sphere& sphere, const Filter* filter, OverlapVisitor& visitor) {
  for (std::size_t k = 0; k < o.shapes.size(); ++k)
    if (query_passes(filter, filter_of(o, k)) && o.shapes.meets_sphere(k, sphere) && !visitor.on_overlap(o.ids[k]))
      return;
}

void brute_overlap_box_visit(const QueryObjects& o, const Box& box, const Filter* filter, OverlapVisitor& visitor) {
  for (std::size_t k = 0; k < o.shapes.size(); ++k)
    if (query_passes(filter, filter_of(o, k)) && o.shapes.meets_box(k, box) && !visitor.on_overlap(o.ids[k])) return;
}

Status Backend::validate_objects(const Shapes& objects) {
  return objects.is_box() ? validate_boxes(objects.boxes) : validate_spheres(objects.spheres);
}

bool Backend::query_ray_first(const Ray& ray, const Filter* filter, RayHit& hit) {
  return brute_ray(query_objects(), ray, filter, hit);
}
void Backend::query_ray_all(const Ray& ray, const Filter* filter, std::vector<RayHit>& hits) {
  brute_ray_all(query_objects(), ray, filter, hits);
}
void Backend::query_ray_visit(const Ray& ray, const Filter* filter, RayVisitor& visitor) {
  brute_ray_visit(query_objects(), ray, filter, visitor);
}
void Backend::query_sphere(const Sphere& sphere, const Filter* filter, std::vector<std::uint32_t>& indices) {
  brute_overlap(query_objects(), sphere, filter, indices);
}
void Backend::query_box(const Box& box, const Filter* filter, std::vector<std::uint32_t>& indices) {
  brute_overlap_box(query_objects(), box, filter, indices);
}
void Backend::query_sphere_visit(const Sphere& sphere, const Filter* filter, OverlapVisitor& visitor) {
  brute_overlap_visit(query_objects(), sphere, filter, visitor);
}
void Backend::query_box_visit(const Box& box, const Filter* filter, OverlapVisitor& visitor) {
  brute_overlap_box_visit(query_objects(), box, filter, visitor);
}

}  // namespace detail

Detector::Detector(std::unique_ptr<detail::Backend> backend) : backend_(std::move(backend)) {}
Detector::~Detector() = default;

std::string_view Detector::name() const { return backend_->name(); }
std::uint64_t Detector::memory_bytes() const { return backend_->memory_bytes(); }
void Detector::wait_for_stage_times(FrameStats& stats) { backend_->wait_for_stage_times(stats); }
const Config& Detector::config() const { return backend_->config(); }
void Detector::set_config(const Config& config) { backend_->set_config(config); }

Status Detector::detect(std::span<const Sphere> spheres, const Camera* camera, FrameResult& out) {
  FrameInput input;
  input.spheres = spheres;
  input.camera = camera;
  return detect(input, out);
}

// The active objects and the static set, for the brute-force queries; reserved for every object,
// so that no allocation follows the active set as it changes.
void Detector::keep_query_objects(detail::Backend& b, const FrameInput& input, const FrameResult& out) {
  const detail::Shapes shapes = detail::Shapes::of(input);
  const detail::StaticSet::Compact& stat = b.static_set_.compact();
  const std::size_t n = shapes.size(), total = n + stat.shapes.size();
  const bool boxes = shapes.is_box() || (n == 0 && stat.shapes.is_box());
  const bool filters = !input.filters.empty() || stat.filtered;  // else every object has Filter{}: no copy
  if (boxes)
    b.query_spheres_.clear();
  else
    b.query_boxes_.clear();
  if (!filters) b.query_filters_.clear();
  if (boxes)
    b.query_boxes_.reserve(total);
  else
    b.query_spheres_.reserve(total);
  b.query_ids_.reserve(total);
  if (filters) b.query_filters_.reserve(total);
  if (n > 0 && std::find(out.state.begin(), out.state.end(), ObjectState::culled) == out.state.end()) {
    // Nothing culled (every frame without culling): every object, copied in chunks on the frame's
    // threads. The vectors keep their size from frame to frame, so resize() zeroes nothing then.
    if (boxes)
      b.query_boxes_.resize(n);
    else
      b.query_spheres_.resize(n);
    b.query_ids_.resize(n);
    if (filters) b.query_filters_.resize(n);
    b.for_chunks_of(n, [&](std::size_t begin, std::size_t end) {
      const auto from = static_cast<std::ptrdiff_t>(begin), to = static_cast<std::ptrdiff_t>(end);
      if (boxes)
        std::copy(input.boxes.begin() + from, input.boxes.begin() + to, b.query_boxes_.begin() + from);
      else
        std::copy(input.spheres.begin() + from, input.spheres.begin() + to, b.query_spheres_.begin() + from);
      std::iota(b.query_ids_.begin() + from, b.query_ids_.begin() + to, static_cast<std::uint32_t>(begin));
      if (filters) {
        if (input.filters.empty())
          std::fill(b.query_filters_.begin() + from, b.query_filters_.begin() + to, Filter{});
        else
          std::copy(input.filters.begin() + from, input.filters.begin() + to, b.query_filters_.begin() + from);
      }
    });
  } else {
    // Runs of objects that are not culled, copied a run at a time.
    b.query_boxes_.clear();
    b.query_spheres_.clear();
    b.query_ids_.clear();
    b.query_filters_.clear();
    for (std::size_t begin = 0; begin < n;) {
      if (out.state[begin] == ObjectState::culled) {
        ++begin;
        continue;
      }
      std::size_t end = begin + 1;
      while (end < n && out.state[end] != ObjectState::culled) ++end;
      const auto from = static_cast<std::ptrdiff_t>(begin), to = static_cast<std::ptrdiff_t>(end);
      if (boxes)
        b.query_boxes_.insert(b.query_boxes_.end(), input.boxes.begin() + from, input.boxes.begin() + to);
      else
        b.query_spheres_.insert(b.query_spheres_.end(), input.spheres.begin() + from, input.spheres.begin() + to);
      const std::size_t at = b.query_ids_.size();
      b.query_ids_.resize(at + (end - begin));
      std::iota(b.query_ids_.begin() + static_cast<std::ptrdiff_t>(at), b.query_ids_.end(),
                static_cast<std::uint32_t>(begin));
      if (filters) {
        if (input.filters.empty())
          b.query_filters_.insert(b.query_filters_.end(), end - begin, Filter{});
        else
          b.query_filters_.insert(b.query_filters_.end(), input.filters.begin() + from, input.filters.begin() + to);
      }
      begin = end;
    }
  }
  // The static set after them.
  for (std::size_t k = 0; k < stat.shapes.size(); ++k) {
    if (boxes)
      b.query_boxes_.push_back(stat.shapes.boxes[k]);
    else
      b.query_spheres_.push_back(stat.shapes.spheres[k]);
    b.query_ids_.push_back(static_index(stat.slots[k]));
    if (filters) b.query_filters_.push_back(stat.filters[k]);
  }
}

Status Detector::set_static_spheres(std::span<const Sphere> spheres, std::span<const Filter> filters) {
  return backend_->static_set_.set(spheres, filters);
}
Status Detector::set_static_boxes(std::span<const Box> boxes, std::span<const Filter> filters) {
  return backend_->static_set_.set(boxes, filters);
}
Result<std::uint32_t> Detector::add_static_sphere(const Sphere& sphere, const Filter& filter) {
  return backend_->static_set_.add(sphere, filter);
}
Result<std::uint32_t> Detector::add_static_box(const Box& box, const Filter& filter) {
  return backend_->static_set_.add(box, filter);
}
Status Detector::move_static_sphere(std::uint32_t k, const Sphere& sphere) {
  return backend_->static_set_.move(k, sphere);
}
Status Detector::move_static_box(std::uint32_t k, const Box& box) { return backend_->static_set_.move(k, box); }
Status Detector::remove_static(std::uint32_t k) { return backend_->static_set_.remove(k); }
void Detector::clear_static() { backend_->static_set_.clear(); }
std::size_t Detector::static_count() const { return backend_->static_set_.size(); }
ShapeKind Detector::static_kind() const {
  return backend_->static_set_.empty() ? ShapeKind::sphere : backend_->static_set_.kind();
}

Status Detector::detect(const FrameInput& input, FrameResult& out) {
  detail::Backend& b = *backend_;
  b.queries_ready_ = false;
  try {
    if (Status s = detail::validate_frame_input(input, b.config(), false); !s) return s;
    if (Status s = b.validate_frame_objects(input); !s) return s;
    if (Status s = detail::validate_static_kind(input, b.static_set_); !s) return s;
    if (Status s = b.run_frame(input, out); !s) return s;
    if (b.config().contact_events) {
      pair_differences(b.previous_pairs_, out.pairs, out.began, out.ended);
      reserve_with_headroom(b.previous_pairs_, out.pairs.size());
      b.previous_pairs_.assign(out.pairs.begin(), out.pairs.end());
    } else {
      // Not kept while events are off: the first frame with them on starts afresh.
      out.began.clear();
      out.ended.clear();
      b.previous_pairs_.clear();
    }
    if (!b.answers_queries()) keep_query_objects(b, input, out);
    b.queries_ready_ = true;
    return {};
  } catch (const std::bad_alloc&) {
    return Status::failure(ErrorKind::out_of_memory,
                           detail::out_of_memory_message(detail::Shapes::of(input).size() + b.static_set_.size(),
                                                         input.camera, b.config()));
  }
}

void Detector::reset_events() { backend_->previous_pairs_.clear(); }

bool Detector::ray_cast(const Ray& ray, RayHit& hit, const Filter* filter) const {
  if (!backend_->queries_ready_ || !valid_ray(ray)) return false;
  return backend_->query_ray_first(ray, filter, hit);
}

void Detector::ray_cast_all(const Ray& ray, std::vector<RayHit>& hits, const Filter* filter) const {
  hits.clear();
  if (!backend_->queries_ready_ || !valid_ray(ray)) return;
  backend_->query_ray_all(ray, filter, hits);
  // Backends append in their own order; the contract is (t, index).
  std::sort(hits.begin(), hits.end(), hit_before);
}

void Detector::ray_cast(const Ray& ray, RayVisitor& visitor, const Filter* filter) const {
  if (backend_->queries_ready_ && valid_ray(ray)) backend_->query_ray_visit(ray, filter, visitor);
}

void Detector::overlap(const Sphere& sphere, std::vector<std::uint32_t>& indices, const Filter* filter) const {
  indices.clear();
  if (!backend_->queries_ready_ || !valid_sphere(sphere)) return;
  backend_->query_sphere(sphere, filter, indices);
  std::sort(indices.begin(), indices.end());
}

void Detector::overlap_box(const Box& box, std::vector<std::uint32_t>& indices, const Filter* filter) const {
  indices.clear();
  if (!backend_->queries_ready_ || !valid_box(box)) return;
  backend_->query_box(box, filter, indices);
  std::sort(indices.begin(), indices.end());
}

void Detector::overlap(const Sphere& sphere, OverlapVisitor& visitor, const Filter* filter) const {
  if (backend_->queries_ready_ && valid_sphere(sphere)) backend_->query_sphere_visit(sphere, filter, visitor);
}

void Detector::overlap_box(const Box& box, OverlapVisitor& visitor, const Filter* filter) const {
  if (backend_->queries_ready_ && valid_box(box)) backend_->query_box_visit(box, filter, visitor);
}

namespace detail {

// |v| <= 1e18 is false for NaN and infinities too.
bool spheres_all_valid(std::span<const Sphere> spheres) {
#if defined(__SSE2__)
  // A sphere is one register (x, y, z, r); two accumulators of "every lane so far valid".
  const __m128 limit = _mm_set1_ps(kMaxCoordinate), sign = _mm_set1_ps(-0.0f), zero = _mm_setzero_ps();
  __m128 ok0 = _mm_cmpeq_ps(zero, zero), ok1 = ok0, radius0 = ok0, radius1 = ok0;
  const float* p = reinterpret_cast<const float*>(spheres.data());
  std::size_t k = 0;
  for (; k + 2 <= spheres.size(); k += 2) {
    const __m128 a = _mm_loadu_ps(p + 4 * k), b = _mm_loadu_ps(p + 4 * k + 4);
    ok0 = _mm_and_ps(ok0, _mm_cmple_ps(_mm_andnot_ps(sign, a), limit));
    ok1 = _mm_and_ps(ok1, _mm_cmple_ps(_mm_andnot_ps(sign, b), limit));
    radius0 = _mm_and_ps(radius0, _mm_cmpge_ps(a, zero));
    radius1 = _mm_and_ps(radius1, _mm_cmpge_ps(b, zero));
  }
  if (k < spheres.size()) {
    const __m128 a = _mm_loadu_ps(p + 4 * k);
    ok0 = _mm_and_ps(ok0, _mm_cmple_ps(_mm_andnot_ps(sign, a), limit));
    radius0 = _mm_and_ps(radius0, _mm_cmpge_ps(a, zero));
  }
  const int ok = _mm_movemask_ps(_mm_and_ps(ok0, ok1)), radius = _mm_movemask_ps(_mm_and_ps(radius0, radius1));
  return ok == 0xF && (radius & 0x8) != 0;  // lane 3: r >= 0
#else
  bool all_valid = true;
  for (const Sphere& s : spheres) {
    const float ax = std::fabs(s.x), ay = std::fabs(s.y), az = std::fabs(s.z), ar = std::fabs(s.r);
    all_valid &=
        (ax <= kMaxCoordinate) & (ay <= kMaxCoordinate) & (az <= kMaxCoordinate) & (ar <= kMaxCoordinate) & (s.r >= 0);
  }
  return all_valid;
#endif
}

bool boxes_all_valid(std::span<const Box> boxes) {
  bool all_valid = true;
  for (const Box& b : boxes)
    for (int k = 0; k < 3; ++k) {
      const float lo = std::fabs(b.min[k]), hi = std::fabs(b.max[k]);
      all_valid &= (lo <= kMaxCoordinate) & (hi <= kMaxCoordinate) & (b.min[k] <= b.max[k]);
    }
  return all_valid;
}

}  // namespace detail

Status validate_spheres(std::span<const Sphere> spheres) {
  if (spheres.size() > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
    return Status::failure(ErrorKind::invalid_input,
                           "too many spheres: " + std::to_string(spheres.size()) + " (at most 2^31 - 1)");
  // A pass without branches first (every frame pays it). Only a failing set is searched for its
  // first bad sphere.
  if (detail::spheres_all_valid(spheres)) return {};
  for (std::size_t k = 0; k < spheres.size(); ++k) {
    const Sphere& s = spheres[k];
    const float v[4] = {s.x, s.y, s.z, s.r};
    for (int c = 0; c < 4; ++c) {
      if (!std::isfinite(v[c]))
        return Status::failure(ErrorKind::invalid_input,
                               "sphere " + std::to_string(k) + ": " + "xyzr"[c] + " is not a finite number");
      if (std::fabs(v[c]) > kMaxCoordinate)
        return Status::failure(ErrorKind::invalid_input, "sphere " + std::to_string(k) + ": |" + "xyzr"[c] + "| = " +
                                                             std::to_string(v[c]) + " exceeds the supported 1e18");
    }
    if (s.r < 0)
      return Status::failure(ErrorKind::invalid_input,
                             "sphere " + std::to_string(k) + ": negative radius " + std::to_string(s.r));
  }
  return {};
}

Status validate_boxes(std::span<const Box> boxes) {
  if (boxes.size() > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
    return Status::failure(ErrorKind::invalid_input,
                           "too many boxes: " + std::to_string(boxes.size()) + " (at most 2^31 - 1)");
  if (detail::boxes_all_valid(boxes)) return {};  // without branches, as validate_spheres()
  static constexpr const char* kNames[2][3] = {{"minx", "miny", "minz"}, {"maxx", "maxy", "maxz"}};
  for (std::size_t i = 0; i < boxes.size(); ++i) {
    const Box& b = boxes[i];
    for (int side = 0; side < 2; ++side)
      for (int k = 0; k < 3; ++k) {
        const float v = side ? b.max[k] : b.min[k];
        if (!std::isfinite(v))
          return Status::failure(ErrorKind::invalid_input,
                                 "box " + std::to_string(i) + ": " + kNames[side][k] + " is not a finite number");
        if (std::fabs(v) > kMaxCoordinate)
          return Status::failure(ErrorKind::invalid_input, "box " + std::to_string(i) + ": |" + kNames[side][k] +
                                                               "| = " + std::to_string(v) +
                                                               " exceeds the supported 1e18");
      }
    for (int k = 0; k < 3; ++k)
      if (!(b.min[k] <= b.max[k]))
        return Status::failure(ErrorKind::invalid_input, "box " + std::to_string(i) + ": " + kNames[0][k] + " = " +
                                                             std::to_string(b.min[k]) + " exceeds " + kNames[1][k] +
                                                             " = " + std::to_string(b.max[k]));
  }
  return {};
}

Status validate_map_size(int width, int height) {
  if (width <= kMaxMapSide && height <= kMaxMapSide &&
      static_cast<std::uint64_t>(width) * static_cast<std::uint64_t>(height) <= kMaxMapPixels)
    return {};
  return Status::failure(ErrorKind::invalid_input,
                         "visibility map " + std::to_string(width) + "x" + std::to_string(height) +
                             " is too large: at most " + std::to_string(kMaxMapSide) + " pixels a side and " +
                             std::to_string(kMaxMapPixels) + " pixels in all (8192x8192); a smaller map works, " +
                             "its counts are scaled to the screen");
}

Status validate_camera(const Camera& c) {
  auto finite3 = [](const float* v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); };
  if (!finite3(c.eye) || !finite3(c.target) || !finite3(c.up))
    return Status::failure(ErrorKind::invalid_input, "camera: eye, target and up must be finite");
  // Bounded like spheres: squared distances stay finite in float, so no projection overflows.
  auto bounded3 = [](const float* v) {
    return std::fabs(v[0]) <= kMaxCoordinate && std::fabs(v[1]) <= kMaxCoordinate && std::fabs(v[2]) <= kMaxCoordinate;
  };
  if (!bounded3(c.eye) || !bounded3(c.target) || !bounded3(c.up))
    return Status::failure(ErrorKind::invalid_input,
                           "camera: eye, target and up must lie within the supported magnitude 1e18");
  if (c.width < 1 || c.height < 1)
    return Status::failure(ErrorKind::invalid_input, "camera: width and height must be at least 1 pixel");
  if (!(c.fov_y_deg > 0 && c.fov_y_deg < 180))
    return Status::failure(ErrorKind::invalid_input, "camera: fov_y_deg must be in (0, 180)");
  if (!(c.near_plane > 0 && c.far_plane > c.near_plane && c.far_plane <= kMaxCoordinate))
    return Status::failure(ErrorKind::invalid_input, "camera: need 0 < near < far <= 1e18");
  const double f[3] = {double(c.target[0]) - c.eye[0], double(c.target[1]) - c.eye[1], double(c.target[2]) - c.eye[2]};
  const double fl = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
  if (!(fl > 0)) return Status::failure(ErrorKind::invalid_input, "camera: eye and target coincide");
  const double u[3] = {c.up[0], c.up[1], c.up[2]};
  const double cx = f[1] * u[2] - f[2] * u[1], cy = f[2] * u[0] - f[0] * u[2], cz = f[0] * u[1] - f[1] * u[0];
  const double ul = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
  if (!(std::sqrt(cx * cx + cy * cy + cz * cz) > 1e-6 * fl * ul))
    return Status::failure(ErrorKind::invalid_input, "camera: up is zero or parallel to the view direction");
  return {};
}

std::string_view stage_name(Stage s) {
  static constexpr std::string_view kNames[] = {"visibility", "count", "cull", "layout", "codes",
                                                "sort",       "build", "fit",  "query",  "shade"};
  static_assert(std::size(kNames) == kStageCount);
  return kNames[static_cast<std::size_t>(s)];
}

double FrameStats::total_ms() const {
  double t = 0;
  for (double v : stage_ms) t += v;
  return t;
}

namespace {
bool default_assert_handler(const char* expr, const char* message, const char* file, int line) {
  std::fprintf(stderr, "%s:%d: viscd assertion failed: %s (%s)\n", file, line, expr, message);
  return false;
}
AssertHandler g_assert_handler = default_assert_handler;
}  // namespace

AssertHandler set_assert_handler(AssertHandler handler) {
  AssertHandler old = g_assert_handler;
  g_assert_handler = handler ? handler : default_assert_handler;
  return old;
}

bool assert_failed(const char* expr, const char* message, const char* file, int line) {
  return g_assert_handler(expr, message, file, line);
}

}  // namespace viscd
