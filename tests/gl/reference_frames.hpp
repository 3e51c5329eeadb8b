#pragma once
// Helpers of the box and static-set tests: random boxes, a camera looking at a point, and the
// comparison of a gl frame with the reference backend's on the same input and static set. The
// id map is held to the standard of the sphere impostors (frame_test.cpp): per object at most 4
// pixels apart (GPU division may move a silhouette pixel; on llvmpipe none moves); everything
// decided from the map (pixels, culling, mu, m, states, pairs) must then be exactly what the
// reference decides from gl's own map, given to it as the caller's id map.

#include <algorithm>
#include <cstdio>
#include <random>
#include <utility>
#include <vector>

#include "cpu/pipeline.hpp"
#include "gl_test_util.hpp"
#include "test_util.hpp"

namespace viscd::test {

/// n boxes with min corners uniform in [-edge/2, edge/2]^3 and each side uniform in
/// [smin, smax] (std::mt19937 seeded with `seed`).
inline std::vector<Box> random_boxes(std::size_t n, float edge, float smin, float smax, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(-edge / 2, edge / 2), side(smin, smax);
  std::vector<Box> b(n);
  for (Box& x : b)
    for (int k = 0; k < 3; ++k) {
      x.min[k] = pos(rng);
      x.max[k] = x.min[k] + side(rng);
    }
  return b;
}

/// A 256 x 144 camera at `eye` looking at `target` (a map of the same size: scale 1).
inline Camera camera_at(float ex, float ey, float ez, float tx = 0, float ty = 0, float tz = 0, float far = 1000) {
  Camera c;
  c.eye[0] = ex, c.eye[1] = ey, c.eye[2] = ez;
  c.target[0] = tx, c.target[1] = ty, c.target[2] = tz;
  c.width = 256;
  c.height = 144;
  c.far_plane = far;
  return c;
}

/// Pixels per id over a map (index 0: background).
inline std::vector<std::uint32_t> id_histogram(std::span<const std::uint32_t> ids, std::size_t objects) {
  std::vector<std::uint32_t> h(objects + 1, 0);
  for (std::uint32_t id : ids) ++h[std::min<std::size_t>(id, objects)];
  return h;
}

/// What compare_with_reference() saw of the maps.
struct MapComparison {
  std::size_t differing_pixels = 0;
  std::uint32_t worst_object = 0;  ///< the largest difference of one object's pixel count
};

/// `ref`'s frame of an input and its map (ids empty when the frame drew none), run once and
/// compared with any number of gl detectors' frames of the same input (the reference's brute-force
/// map costs pixels x objects ray casts, the most of a test's time under the sanitizers).
struct ReferenceFrame {
  FrameResult result;
  std::vector<std::uint32_t> ids;
  int width = 0, height = 0;
};

inline ReferenceFrame run_reference(Detector& ref, const FrameInput& in) {
  ReferenceFrame r;
  const Status s = ref.detect(in, r.result);
  EXPECT_TRUE(s.ok()) << s.error();
  if (!s.ok()) return r;
  const detail::VisibilityMap& map = detail::backend_as<detail::PipelineDetector>(ref).visibility_map();
  r.ids.assign(map.ids.begin(), map.ids.end());
  r.width = map.width;
  r.height = map.height;
  return r;
}

/// Runs `in` on `gl` into `a` and compares it with `ref`'s frame of it, `r` (run_reference(): a
/// reference or cpu detector, whose box maps are equal bit for bit, with the same Config and
/// static set). Without a rendered map, pairs and states must be equal. With one (a camera and a
/// Config that uses the map): the maps per object within 4 pixels, static objects included; then
/// `ref` runs again on gl's map (static ids written as background, as the caller's map holds them)
/// and pixels, states, active count, mu, m and pairs must equal gl's exactly; when the maps are
/// equal, so must the reference's own frame be. `sync` says whether gl chose m from this frame
/// (sync_layout or a first frame): only then is its m compared.
inline MapComparison compare_with_reference(GlUnderTest& gl, Detector& ref, const FrameInput& in, FrameResult& a,
                                            const ReferenceFrame& r, bool sync = true) {
  MapComparison m;
  const Status sa = gl.detect(in, a);
  EXPECT_TRUE(sa.ok()) << sa.error();
  if (!sa.ok()) return m;
  const FrameResult& b = r.result;
  EXPECT_EQ(a.stats.objects, b.stats.objects);
  EXPECT_EQ(a.stats.static_objects, b.stats.static_objects);
  const std::size_t n = a.stats.objects, total = n + a.stats.static_objects;
  if (r.ids.empty()) {
    EXPECT_TRUE(a.pairs == b.pairs);
    EXPECT_TRUE(a.state == b.state);
    EXPECT_EQ(a.stats.active, b.stats.active);
    return m;
  }
  const std::vector<std::uint32_t> ids = gl.inspect().read_id_map();
  EXPECT_EQ(ids.size(), r.ids.size());
  if (ids.size() != r.ids.size()) return m;
  for (std::size_t i = 0; i < ids.size(); ++i) m.differing_pixels += ids[i] != r.ids[i];
  const auto hg = id_histogram(ids, total), hr = id_histogram(r.ids, total);
  for (std::size_t k = 1; k <= total; ++k) {
    const std::uint32_t d = hg[k] > hr[k] ? hg[k] - hr[k] : hr[k] - hg[k];
    EXPECT_LE(d, 4u) << "object " << k - 1 << ": gl " << hg[k] << " pixels, reference " << hr[k];
    m.worst_object = std::max(m.worst_object, d);
  }
  if (m.differing_pixels == 0) {
    EXPECT_TRUE(a.pairs == b.pairs);
    EXPECT_TRUE(a.state == b.state);
    EXPECT_TRUE(a.pixels == b.pixels);
  }
  // The reference deciding from gl's map.
  std::vector<std::uint32_t> moving_ids = ids;
  for (std::uint32_t& id : moving_ids)
    if (id > n) id = 0;
  FrameInput from_map = in;
  from_map.id_map = moving_ids;
  from_map.id_map_width = r.width;
  from_map.id_map_height = r.height;
  const Config own = ref.config();
  Config no_shade = own;
  no_shade.shade = false;  // the caller's map has no normals
  ref.set_config(no_shade);
  FrameResult c;
  const Status sc = ref.detect(from_map, c);
  ref.set_config(own);
  EXPECT_TRUE(sc.ok()) << sc.error();
  if (!sc.ok()) return m;
  EXPECT_TRUE(a.pixels == c.pixels);
  EXPECT_TRUE(a.state == c.state);
  EXPECT_TRUE(a.pairs == c.pairs);
  EXPECT_EQ(a.stats.active, c.stats.active);
  EXPECT_EQ(a.stats.mean_pixels, c.stats.mean_pixels);
  if (sync) {
    EXPECT_EQ(a.stats.bits, c.stats.bits);
  }
  return m;
}

/// compare_with_reference() with `ref`'s frame run here, into `b`.
inline MapComparison compare_with_reference(GlUnderTest& gl, Detector& ref, const FrameInput& in, FrameResult& a,
                                            FrameResult& b, bool sync = true) {
  ReferenceFrame r = run_reference(ref, in);
  const MapComparison m = compare_with_reference(gl, ref, in, a, r, sync);
  b = std::move(r.result);
  return m;
}

}  // namespace viscd::test
