// Detector: the frame around a backend's run_frame() (checks, contact events, what queries
// keep), the queries' checks, and the static set's calls.
#include <algorithm>
#include <cstring>
#include <exception>
#include <new>
#include <numeric>
#include <string>
#include <type_traits>

#include "core/backend.hpp"
#include "core/frame_rules.hpp"
#include "core/query_rules.hpp"
#include "viscd/detector.hpp"

namespace viscd {

// ---- Detector: the frame around run_frame(), contact events, queries ----

namespace {

template <class T>
void reserve_with_headroom(std::vector<T>& v, std::size_t n) {
  if (v.capacity() < n) v.reserve(n + n / 2);
}

// began = now \ before, ended = before \ now, both sorted: one merge of the two sorted lists.
// The outputs only grow to the largest count seen, so a steady state allocates nothing. Most
// frames keep most pairs, so the two lists agree over long stretches (at any offsets: each event
// shifts one against the other): blocks of kRun pairs that compare equal as bytes are passed at
// once, and only a block that differs is merged pair by pair.
void pair_differences(const std::vector<Pair>& before, const std::vector<Pair>& now, std::vector<Pair>& began,
                      std::vector<Pair>& ended) {
  static_assert(sizeof(Pair) == 2 * sizeof(std::uint32_t) && std::has_unique_object_representations_v<Pair>);
  constexpr std::size_t kRun = 32;
  began.clear();
  ended.clear();
  // Room for the most each can hold, with headroom as the pair count drifts.
  reserve_with_headroom(began, now.size());
  reserve_with_headroom(ended, before.size());
  const Pair *b = before.data(), *const be = b + before.size();
  const Pair *n = now.data(), *const ne = n + now.size();
  while (b != be && n != ne) {
    if (be - b >= static_cast<std::ptrdiff_t>(kRun) && ne - n >= static_cast<std::ptrdiff_t>(kRun) &&
        std::memcmp(b, n, kRun * sizeof(Pair)) == 0) {
      b += kRun;
      n += kRun;
      continue;
    }
    // At most a block's worth merged one by one before the next block is compared.
    for (std::size_t step = 0; step < kRun && b != be && n != ne; ++step) {
      if (*b < *n) {
        ended.push_back(*b++);
      } else if (*n < *b) {
        began.push_back(*n++);
      } else {
        ++b, ++n;
      }
    }
  }
  ended.insert(ended.end(), b, be);
  began.insert(began.end(), n, ne);
}

}  // namespace

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
  } catch (const std::exception& e) {
    // No exception leaves detect() (the header's promise): anything else a backend or the
    // standard library throws (a length_error, a system_error from a thread) fails the frame.
    return Status::failure(ErrorKind::backend_failure, std::string("backend '") + std::string(b.name()) +
                                                           "' failed with an exception: " + e.what());
  } catch (...) {
    return Status::failure(ErrorKind::backend_failure,
                           "backend '" + std::string(b.name()) + "' failed with an exception of an unknown type");
  }
}

void Detector::reset_events() { backend_->previous_pairs_.clear(); }

bool Detector::ray_cast(const Ray& ray, RayHit& hit, const Filter* filter) const {
  if (!backend_->queries_ready_ || !detail::valid_ray(ray)) return false;
  return backend_->query_ray_first(ray, filter, hit);
}

void Detector::ray_cast_all(const Ray& ray, std::vector<RayHit>& hits, const Filter* filter) const {
  hits.clear();
  if (!backend_->queries_ready_ || !detail::valid_ray(ray)) return;
  backend_->query_ray_all(ray, filter, hits);
  // Backends append in their own order; the contract is (t, index).
  std::sort(hits.begin(), hits.end(), detail::hit_before);
}

void Detector::ray_cast(const Ray& ray, RayVisitor& visitor, const Filter* filter) const {
  if (backend_->queries_ready_ && detail::valid_ray(ray)) backend_->query_ray_visit(ray, filter, visitor);
}

void Detector::overlap(const Sphere& sphere, std::vector<std::uint32_t>& indices, const Filter* filter) const {
  indices.clear();
  if (!backend_->queries_ready_ || !detail::valid_query_sphere(sphere)) return;
  backend_->query_sphere(sphere, filter, indices);
  std::sort(indices.begin(), indices.end());
}

void Detector::overlap_box(const Box& box, std::vector<std::uint32_t>& indices, const Filter* filter) const {
  indices.clear();
  if (!backend_->queries_ready_ || !detail::valid_query_box(box)) return;
  backend_->query_box(box, filter, indices);
  std::sort(indices.begin(), indices.end());
}

void Detector::overlap(const Sphere& sphere, OverlapVisitor& visitor, const Filter* filter) const {
  if (backend_->queries_ready_ && detail::valid_query_sphere(sphere))
    backend_->query_sphere_visit(sphere, filter, visitor);
}

void Detector::overlap_box(const Box& box, OverlapVisitor& visitor, const Filter* filter) const {
  if (backend_->queries_ready_ && detail::valid_query_box(box)) backend_->query_box_visit(box, filter, visitor);
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

}  // namespace viscd
