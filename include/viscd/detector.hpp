#pragma once
/// \file detector.hpp
/// The detector an engine calls, a factory per backend, and the rules every backend shares.

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "viscd/config.hpp"
#include "viscd/frame.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd {

namespace detail {
class Backend;  // what each backend implements (src/core/backend.hpp); not part of the API
struct DetectorAccess;
}  // namespace detail

/// The callback of Detector::ray_cast(ray, visitor) (after Box2D's b2RayCastCallback): called
/// once for each hit the query finds, from the calling thread, during the call. What it returns
/// steers the query; the ray's max t starts at Ray::max_t and never grows:
///   - 0 (either sign): stop; no further calls;
///   - a value v > 0: the max t becomes min(max t, v). Returning hit.t clips the ray to the hit
///     (the closest-hit search); returning the current max t (or infinity) keeps every hit;
///   - a negative value or NaN: the hit is ignored and the max t stays (filtering).
/// A closest-hit visitor that must break ties at t = 0 by index (as Detector::ray_cast does)
/// returns the smallest positive float for a hit at t = 0 rather than 0, which would stop.
class RayVisitor {
 public:
  virtual ~RayVisitor() = default;
  /// One hit: the object's index and its t (ray_hits_sphere()), with t <= the current max t.
  /// Returns the new max t, as above. Must not call the detector.
  virtual float on_hit(const RayHit& hit) = 0;
};

/// The callback of Detector::overlap(sphere, visitor) and overlap_box(box, visitor) (after Jolt's collectors'
/// ShouldEarlyOut): called once for each overlapping object, from the calling thread, during the call.
class OverlapVisitor {
 public:
  virtual ~OverlapVisitor() = default;
  /// One overlapping object's index. Returns true to go on, false to stop the query (no further
  /// calls). Must not call the detector.
  virtual bool on_overlap(std::uint32_t index) = 0;
};

/// Finds every overlapping pair of objects (spheres or axis-aligned boxes), frame after frame, and answers ray and
/// overlap queries on the last frame. Made by a factory below (make_cpu_detector(), make_detector(),
/// make_gl_detector()); the backend it runs is fixed for its lifetime.
///
/// Threading: detect(), the static set's calls and set_config() must not run at once with any
/// other call on the same detector. Between frames, the queries (ray_cast, ray_cast_all,
/// overlap, overlap_box; const) may run from any number of threads at once on the cpu and
/// reference backends (game AI, audio and gameplay jobs), with the answers one thread gets; on gl
/// and cuda from one thread at a time (gl: the thread whose context is current). The detector
/// may use worker threads internally (Config::threads, Config::executor). Lifetime: the input's
/// spans need only live for the call.
class Detector {
 public:
  ~Detector();
  Detector(const Detector&) = delete;
  Detector& operator=(const Detector&) = delete;

  /// Runs one frame. Without a camera (and without an id map) no visibility stages run and every
  /// object is active; with a camera and Config::culling, objects below lambda screen pixels are
  /// culled. Fails (and leaves `out` unspecified) with ErrorKind::invalid_input on invalid
  /// spheres (non-finite, negative radius, beyond kMaxCoordinate), an invalid camera, a
  /// visibility map beyond kMaxMapSide or kMaxMapPixels, filters that are neither empty nor one
  /// per sphere, an id map whose size is not id_map_width x id_map_height or whose ids exceed the
  /// number of spheres, an id map and a gl texture together, FrameInput::moved not ascending,
  /// repeating or out of range (or given without moved_listed), a Config::rest_margin that is
  /// negative or not finite, a moved list that Config::verify_moved finds short, negative
  /// Config::threads or more than 2^31 - 1 objects; with ErrorKind::unsupported_input on input this backend does not
  /// take (the message says which); with ErrorKind::pair_cap when the pairs exceed
  /// Config::pair_memory_cap; with ErrorKind::out_of_memory when memory runs out (the message
  /// names the frame's size); with ErrorKind::backend_failure when the backend fails (a GL
  /// error). A failed frame leaves the contact events' previous frame as it was, and queries see
  /// no objects until the next frame succeeds. No exception leaves detect().
  [[nodiscard]] Status detect(const FrameInput& input, FrameResult& out);
  /// detect() with spheres and a camera only (no filters, no id map).
  [[nodiscard]] Status detect(std::span<const Sphere> spheres, const Camera* camera, FrameResult& out);

  /// The static set: objects that do not move (terrain, buildings, props; sleeping bodies an
  /// engine parks there), handed over once and then changed piecemeal: adding, removing or moving
  /// k of them costs about k, not a rebuild. Each frame reports, beside the pairs of its moving
  /// objects, the pair of each active moving object with each static object it overlaps, as
  /// {i, static_index(k)}; never a pair of two static objects. Static objects are never culled,
  /// occlude in the detector's own visibility map (a wall hides what is behind it; the caller's
  /// id map shows them as background), are not counted in mu, and are seen by the queries (under
  /// static_index(k)). Each has a Filter (default Filter{}) that applies as a moving object's does.
  ///
  /// An object lives in a slot k, kept until it is removed; add_static_*() takes the smallest
  /// free slot, set_static_*() fills slots 0..n-1. The set holds spheres or boxes (its kind is
  /// that of its first object; an empty set takes either), and a frame's moving objects must be
  /// of the same kind while the set is not empty. Invalid shapes (validate_spheres(),
  /// validate_boxes()), a shape of the other kind and an unknown slot fail with
  /// ErrorKind::invalid_input and change nothing. Changes take effect at the next detect().
  ///
  /// set_static_spheres / set_static_boxes: replaces the set (filters: empty, or one per object).
  [[nodiscard]] Status set_static_spheres(std::span<const Sphere> spheres, std::span<const Filter> filters = {});
  [[nodiscard]] Status set_static_boxes(std::span<const Box> boxes, std::span<const Filter> filters = {});
  /// Adds one object; returns its slot k (reported as static_index(k)).
  [[nodiscard]] Result<std::uint32_t> add_static_sphere(const Sphere& sphere, const Filter& filter = {});
  [[nodiscard]] Result<std::uint32_t> add_static_box(const Box& box, const Filter& filter = {});
  /// Moves (or reshapes) the object in slot k; its filter stays.
  [[nodiscard]] Status move_static_sphere(std::uint32_t k, const Sphere& sphere);
  [[nodiscard]] Status move_static_box(std::uint32_t k, const Box& box);
  /// Removes the object in slot k; the slot is free for a later add.
  [[nodiscard]] Status remove_static(std::uint32_t k);
  /// Empties the static set.
  void clear_static();
  /// Objects in the static set.
  [[nodiscard]] std::size_t static_count() const;
  /// The kind of the static set's objects (ShapeKind::sphere while it is empty).
  [[nodiscard]] ShapeKind static_kind() const;

  /// Forgets the previous frame of the contact events: the next frame's `began` holds all its
  /// pairs and its `ended` is empty.
  void reset_events();

  /// Queries on the last successful frame: they see its active objects (culled ones are
  /// invisible) at the positions that frame was given, and the static set as it was then (static
  /// objects are reported as static_index(k)). A ray hits a sphere by ray_hits_sphere() and a box
  /// by ray_hits_box(); a ray with a zero or non-finite direction, a non-finite origin, or a
  /// max_t that is negative or NaN hits nothing. A query sphere overlaps a sphere by
  /// spheres_overlap() and a box by sphere_overlaps_box(); a query box overlaps a sphere by
  /// sphere_overlaps_box() and a box by boxes_overlap().
  ///
  /// `filter` (optional; not kept after the call): when given, an object is reported only when
  /// pair_passes_filter(*filter, its filter), its filter being the one the last frame's
  /// FrameInput::filters gave it (Filter{} when that frame had none). Without it, the frame's
  /// filters do not apply. Every query is exact: each backend answers as brute force over the
  /// active objects would, bit for bit.
  ///
  /// ray_cast: the first hit (smallest t, ties to the smaller index); false when there is none.
  [[nodiscard]] bool ray_cast(const Ray& ray, RayHit& hit, const Filter* filter = nullptr) const;
  /// Every hit, sorted by (t, index); `hits` is cleared first (its capacity is reused).
  void ray_cast_all(const Ray& ray, std::vector<RayHit>& hits, const Filter* filter = nullptr) const;
  /// Calls visitor.on_hit() for the hits of `ray` in an unspecified order, with the ray's max t
  /// lowered by what the visitor returns (RayVisitor). Guarantees: each object at most once; only
  /// hits with t <= the max t at the time they are found; every hit with t <= the final max t
  /// (since the max only decreases, a visitor that returns hit.t finds the first hit); no call
  /// after the visitor returned 0. Nothing is called for an invalid ray.
  void ray_cast(const Ray& ray, RayVisitor& visitor, const Filter* filter = nullptr) const;
  /// The active objects that overlap `sphere` by spheres_overlap(), sorted by index; cleared
  /// first. A sphere that validate_spheres() refuses overlaps nothing.
  void overlap(const Sphere& sphere, std::vector<std::uint32_t>& indices, const Filter* filter = nullptr) const;
  /// The active objects that overlap `box` (sphere_overlaps_box(), boxes_overlap()), sorted by index;
  /// cleared first. A box with a non-finite bound or min > max on an axis overlaps nothing.
  /// (Named apart from overlap(): a braced list such as overlap({x, y, z, r}, indices) would
  /// otherwise be ambiguous, since it can initialise a Box too.)
  void overlap_box(const Box& box, std::vector<std::uint32_t>& indices, const Filter* filter = nullptr) const;
  /// Calls visitor.on_overlap() once for each active object that overlaps `sphere` (as the list
  /// form), in an unspecified order, until it returns false. Nothing for an invalid sphere.
  void overlap(const Sphere& sphere, OverlapVisitor& visitor, const Filter* filter = nullptr) const;
  /// Calls visitor.on_overlap() once for each active object that overlaps `box` (as the list
  /// form), in an unspecified order, until it returns false. Nothing for an invalid box.
  void overlap_box(const Box& box, OverlapVisitor& visitor, const Filter* filter = nullptr) const;

  /// Backend name: "reference", "cpu", "gl", "cuda".
  [[nodiscard]] std::string_view name() const;

  /// Working memory the backend holds now, in bytes: visibility map, counts, codes, sort
  /// buffers, tree, pair buffers (GPU memory for gl; there the driver's own figure, from
  /// GL_NVX_gpu_memory_info, when it offers one). Grows with the largest frame seen so far.
  [[nodiscard]] std::uint64_t memory_bytes() const;

  /// Backends that time stages on a GPU report a frame's times one frame late, so that timing
  /// never stalls the pipeline. After a frame whose times are needed now (a single-frame run),
  /// call this: it waits until that frame's times are known and writes them into `stats`.
  /// CPU backends report times at once; for them this does nothing.
  void wait_for_stage_times(FrameStats& stats);

  [[nodiscard]] const Config& config() const;
  /// Changes settings; takes effect on the next detect().
  void set_config(const Config& config);

 private:
  friend struct detail::DetectorAccess;
  explicit Detector(std::unique_ptr<detail::Backend> backend);
  static void keep_query_objects(detail::Backend& b, const FrameInput& input, const FrameResult& out);
  std::unique_ptr<detail::Backend> backend_;
};

/// Brute force O(N^2) pairs and a per-pixel ray cast visibility map: the test oracle.
[[nodiscard]] std::unique_ptr<Detector> make_reference_detector(const Config& config = {});
/// The fast CPU backend: LBVH and a tiled sphere rasterizer on all cores (or Config::executor).
[[nodiscard]] std::unique_ptr<Detector> make_cpu_detector(const Config& config = {});
/// A backend by name ("reference", "cpu", "gl" when built with VISCD_ENABLE_GL, "cuda" when built
/// with VISCD_ENABLE_CUDA: viscd/cuda.hpp).
[[nodiscard]] Result<std::unique_ptr<Detector>> make_detector(std::string_view backend, const Config& config = {});

/// Largest number of pairs N objects can produce, N(N-1)/2: the capacity that always suffices
/// (with a static set of K objects add N K).
[[nodiscard]] constexpr std::uint64_t max_pairs_bound(std::uint64_t n) { return n < 2 ? 0 : n * (n - 1) / 2; }

/// The overlap test every backend uses, evaluated in float without FMA: |c_i - c_j| <= r_i + r_j
/// (touching counts; docs/architecture.md).
[[nodiscard]] bool spheres_overlap(const Sphere& a, const Sphere& b);

/// Whether objects with these filters may be reported as a pair:
/// `(a.group & b.mask) != 0 && (b.group & a.mask) != 0`.
[[nodiscard]] constexpr bool pair_passes_filter(const Filter& a, const Filter& b) {
  return (a.group & b.mask) != 0 && (b.group & a.mask) != 0;
}

/// The ray-sphere test every backend and query uses: true when a point origin + t * dir with
/// 0 <= t <= ray.max_t lies inside or on the sphere, with `t` the smallest such t rounded to float
/// (0 when the origin is inside or on it). Evaluated in double from the float inputs, the same
/// operations everywhere (docs/architecture.md, "Queries"), so that every backend's answer is the
/// same bit for bit. A zero direction hits nothing.
[[nodiscard]] bool ray_hits_sphere(const Ray& ray, const Sphere& sphere, float& t);

/// The sphere-box test every backend and query uses: true when the squared distance from the
/// sphere's centre to the closed box is at most r^2 (touching counts; a box inside the sphere or
/// the centre inside the box overlaps). Evaluated in double from the float inputs, per axis
/// e = the distance from the centre to the box's interval (0 inside it), d2 = (e_x^2 + e_y^2) +
/// e_z^2 <= r^2 (docs/architecture.md, "Queries"), so that every backend's answer is the same bit
/// for bit. False for a box with a non-finite bound or min > max on an axis, or a sphere that
/// validate_spheres() refuses.
[[nodiscard]] bool sphere_overlaps_box(const Sphere& sphere, const Box& box);

/// The box test every backend uses, in float: min_i <= max_j && min_j <= max_i on every axis
/// (closed boxes: touching faces, edges and corners count; a point box is a point). False when a
/// bound is NaN.
[[nodiscard]] bool boxes_overlap(const Box& a, const Box& b);
/// The ray-box test every backend and query uses: true when a point origin + t * dir with
/// 0 <= t <= ray.max_t lies in the closed box, with `t` the smallest such t rounded to float (0
/// when the origin is inside or on it). Slabs in double from the float inputs: along an axis with
/// dir 0 the origin must lie within [min, max]; else the slab is entered at (min - o) / d and left
/// at (max - o) / d (swapped for d < 0); t = the largest entry (and 0), hit when it is at most the
/// smallest exit (and max_t) (docs/architecture.md, "Queries"). A zero direction hits nothing;
/// an invalid box (validate_boxes()) is never hit.
[[nodiscard]] bool ray_hits_box(const Ray& ray, const Box& box, float& t);
/// Checks boxes for the input rules (every bound finite with magnitude <= kMaxCoordinate,
/// min <= max on each axis) and the object limit; the error names the first bad box by index.
[[nodiscard]] Status validate_boxes(std::span<const Box> boxes);
/// Checks spheres for the input rules (finite, 0 <= r, magnitudes <= kMaxCoordinate) and the
/// object limit; the error names the first bad sphere by index.
[[nodiscard]] Status validate_spheres(std::span<const Sphere> spheres);
/// Checks a visibility map size against kMaxMapSide and kMaxMapPixels; the error names "WxH".
[[nodiscard]] Status validate_map_size(int width, int height);
/// Checks a camera (positive size, 0 < fov < 180, 0 < near < far, eye != target, up not parallel,
/// every coordinate and plane distance finite and at most kMaxCoordinate in magnitude).
[[nodiscard]] Status validate_camera(const Camera& camera);

}  // namespace viscd
