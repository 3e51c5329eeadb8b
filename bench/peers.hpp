#pragma once
// Broadphases compared by viscd_peers: viscd itself and its peers, Bullet and FCL
// (docs/benchmarks.md).
//
// Every method keeps its own structure between frames, is given the spheres of each frame and
// must return the exact pairs: candidates from its broadphase filtered by viscd::spheres_overlap,
// the test every viscd backend uses, so that all methods produce the same pair set (the driver
// checks that every frame). Pairs come back as (i < j) in any order; sorting them is viscd's
// job only (it is inside viscd's time and outside the peers', which favours the peers).

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "viscd/types.hpp"

namespace viscd::bench {

/// The box every centre stays in (the scene's objects move on circles about the y axis), with
/// room for the largest radius; sweep-and-prune needs it to quantise coordinates.
struct WorldBounds {
  float lo[3] = {0, 0, 0};
  float hi[3] = {0, 0, 0};
  float max_abs = 0;  ///< largest |coordinate| of any point of any sphere
};

/// One broadphase under test. Not thread-safe.
class Method {
 public:
  virtual ~Method() = default;
  Method() = default;
  Method(const Method&) = delete;
  Method& operator=(const Method&) = delete;

  /// Short name used in tables and CSV ("viscd", "bullet_dbvt", ...).
  [[nodiscard]] virtual std::string_view name() const = 0;
  /// Builds the structure over the first frame's spheres; not timed. The number of spheres stays
  /// fixed afterwards. Returns "" or an error message.
  [[nodiscard]] virtual std::string init(std::span<const Sphere> spheres, const WorldBounds& world) = 0;
  /// One frame, timed by the caller: moves every object to `spheres` (same count as in init),
  /// queries, and returns every exact pair (i < j), each once, in any order. The span stays
  /// valid until the next call. Returns false (and sets `error`) on failure.
  [[nodiscard]] virtual bool frame(std::span<const Sphere> spheres, std::span<const Pair>& pairs,
                                   std::string& error) = 0;
  /// Candidate pairs the broadphase handed to the exact test in the last frame (its pair cache or
  /// callback count); 0 when the method does not expose it (viscd tests candidates internally).
  [[nodiscard]] virtual std::uint64_t candidates() const { return 0; }
};

/// viscd's cpu backend without camera (every object active), `threads` as Config::threads.
[[nodiscard]] std::unique_ptr<Method> make_viscd_method(std::string name, int threads);

/// Names of the peers built into this binary, in the order they run.
[[nodiscard]] std::vector<std::string> peer_names();
/// A peer by name from peer_names(); nullptr for an unknown name.
[[nodiscard]] std::unique_ptr<Method> make_peer(std::string_view name);

#ifdef VISCD_BENCH_HAVE_BULLET
/// Bullet's dynamic AABB tree broadphase (btDbvtBroadphase, default settings).
[[nodiscard]] std::unique_ptr<Method> make_bullet_dbvt();
/// Bullet's 32-bit sweep and prune (bt32BitAxisSweep3) over the world bounds, without its
/// ray-cast accelerator (a second, dbvt broadphase kept in step only for ray queries).
[[nodiscard]] std::unique_ptr<Method> make_bullet_sap();
#endif
#ifdef VISCD_BENCH_HAVE_FCL
/// FCL's dynamic AABB tree manager (fcl::DynamicAABBTreeCollisionManager<float>), sphere objects.
[[nodiscard]] std::unique_ptr<Method> make_fcl_dynamic_tree();
#endif

}  // namespace viscd::bench
