#include "cpu/cpu_detector.hpp"

#include "cpu/parallel.hpp"

namespace viscd {
namespace detail {

const BucketBroadphase& CpuDetector::unpaired_tree() {
  if (!unpaired_built_) {
    const ExecutorScope scope(config_.executor);
    const int threads = resolve_threads(config_.threads, config_.executor ? config_.executor->concurrency() : 0);
    const std::size_t n = unpaired_spheres_.size();
    if (iota_.size() < n) {
      const std::size_t old = iota_.size();
      iota_.resize(n);
      for (std::size_t k = old; k < n; ++k) iota_[k] = static_cast<std::uint32_t>(k);
    }
    unpaired_tree_.build(unpaired_spheres_, std::span<const std::uint32_t>(iota_.data(), n), 32, config_.layout,
                         threads, unpaired_stats_);
    unpaired_built_ = true;
  }
  return unpaired_tree_;
}

// Each query searches the main tree, then the unpaired objects' tree (built on the first query
// that needs it). Detector sorts the lists.

bool CpuDetector::query_ray_first(const Ray& ray, const Filter* filter, RayHit& hit) {
  bool found = broadphase_.ray_first(ray, {}, filter, hit, false);
  if (!unpaired_ids_.empty()) found = unpaired_tree().ray_first(ray, unpaired_objects(), filter, hit, found);
  return found;
}

void CpuDetector::query_ray_all(const Ray& ray, const Filter* filter, std::vector<RayHit>& hits) {
  broadphase_.ray_all(ray, {}, filter, hits);
  if (!unpaired_ids_.empty()) unpaired_tree().ray_all(ray, unpaired_objects(), filter, hits);
}

void CpuDetector::query_ray_visit(const Ray& ray, const Filter* filter, RayVisitor& visitor) {
  float max_t = ray.max_t;  // lowered by the visitor in the first tree, it prunes the second
  if (!broadphase_.ray_visit(ray, {}, filter, max_t, visitor)) return;
  if (!unpaired_ids_.empty()) (void)unpaired_tree().ray_visit(ray, unpaired_objects(), filter, max_t, visitor);
}

void CpuDetector::query_sphere(const Sphere& sphere, const Filter* filter, std::vector<std::uint32_t>& indices) {
  broadphase_.overlap(sphere, {}, filter, indices);
  if (!unpaired_ids_.empty()) unpaired_tree().overlap(sphere, unpaired_objects(), filter, indices);
}

void CpuDetector::query_box(const Box& box, const Filter* filter, std::vector<std::uint32_t>& indices) {
  broadphase_.overlap_box(box, {}, filter, indices);
  if (!unpaired_ids_.empty()) unpaired_tree().overlap_box(box, unpaired_objects(), filter, indices);
}

void CpuDetector::query_sphere_visit(const Sphere& sphere, const Filter* filter, OverlapVisitor& visitor) {
  if (!broadphase_.overlap_visit(sphere, {}, filter, visitor)) return;
  if (!unpaired_ids_.empty()) (void)unpaired_tree().overlap_visit(sphere, unpaired_objects(), filter, visitor);
}

void CpuDetector::query_box_visit(const Box& box, const Filter* filter, OverlapVisitor& visitor) {
  if (!broadphase_.overlap_box_visit(box, {}, filter, visitor)) return;
  if (!unpaired_ids_.empty()) (void)unpaired_tree().overlap_box_visit(box, unpaired_objects(), filter, visitor);
}

}  // namespace detail

std::unique_ptr<Detector> make_cpu_detector(const Config& config) {
  return detail::DetectorAccess::wrap(std::make_unique<detail::CpuDetector>(config));
}

}  // namespace viscd
