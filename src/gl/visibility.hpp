#pragma once
// Stages 1, 2 and 9 of the gl backend, the part that owns the visibility map: the G-buffer
// (ids, view depth, normals, depth buffer), the draws that fill it (spheres as impostors or
// meshes, or splatted by compute shaders; boxes as cubes whose fragments ray-cast the box), the pixel count per object
// (ssbo or atomic_uint), the caller's id map (an array uploaded into the id texture, or the caller's own texture
// checked and read), and the shading that reads the G-buffer back. Counting and shading live here because both read the
// map this part draws.

#include <cstdint>
#include <span>
#include <vector>

#include "gl/frame_data.hpp"
#include "gl/objects.hpp"
#include "gl/program.hpp"
#include "gl/shaders/shared/layout.h"
#include "gl/stage_timers.hpp"
#include "viscd/config.hpp"
#include "viscd/frame.hpp"
#include "viscd/gl.hpp"
#include "viscd/result.hpp"

namespace viscd::gl {

class Visibility {
 public:
  /// The part reads `config` and `options` (the detector's, which may change between frames) at
  /// each frame; it writes FrameData::counts (stage 2) and reads FrameData::states (stage 9).
  Visibility(FrameData& frame, StageTimers& timers, const Config& config, const GlOptions& options)
      : frame_(frame), timers_(timers), config_(config), options_(options) {}

  /// Builds the programs and the map-independent objects, reads the atomic-counter limits. The
  /// context must be current.
  [[nodiscard]] Status init();
  /// Stages 1-2 with the frame's camera (FrameData::rig): the G-buffer of `objects` objects (the
  /// static ones included), then their counts into FrameData::counts in GlOptions::counter's mode. Fails before any
  /// work when the atomic_uint mode cannot count so many objects on this driver.
  [[nodiscard]] Status render(std::uint32_t objects);
  /// Stage 2 on the caller's map: FrameInput::id_map uploaded into the id texture, or
  /// FrameInput::gl_id_texture checked (a texture, R32UI, the map's size) and read. Always the
  /// ssbo counter, which counts ids above N (the moving objects) into FrameInfo.id_check.
  [[nodiscard]] Status count_callers_map(const FrameInput& in);
  /// The frame's error when the caller's map held ids above N (FrameInfo.id_check as the final
  /// wait read it back); success otherwise.
  [[nodiscard]] static Status id_check(const FrameInput& in, const shader::FrameInfo& info);
  /// Stage 9 from the G-buffer and FrameData::states, and the image back into `out`; clears the
  /// image without a camera or without Config::shade.
  void shade(FrameResult& out);
  /// Bytes of the G-buffer, the mesh and the image buffer (Detector::memory_bytes()).
  [[nodiscard]] std::uint64_t memory_bytes() const;

  // ---- for tests (test_access.hpp); the caller makes the context current ----

  /// After a frame with a camera: the id map, rows top to bottom (object index + 1, 0 = none).
  [[nodiscard]] std::vector<std::uint32_t> read_id_map();
  /// Stage 2 alone on a given id map (rows top to bottom) of `objects` objects, in
  /// GlOptions::counter's mode; the counts read back.
  [[nodiscard]] Result<std::vector<std::uint32_t>> count_id_map(std::span<const std::uint32_t> ids, int width,
                                                                int height, std::uint32_t objects);

 private:
  /// (Re)creates the G-buffer when the map's size changes.
  void ensure_map(int w, int h);
  /// Stage 1: clears the G-buffer and draws n objects into it.
  void draw_gbuffer(std::uint32_t n);
  /// Stage 1 for GlGeometry::splat (spheres): splat_plan.comp, splat.comp's two passes and
  /// splat_resolve.comp.
  void splat_gbuffer(std::uint32_t n);
  /// Counts the ids of `ids` (w x h) into FrameData::counts[0..n) in the given mode (ssbo: ids
  /// above n into FrameInfo.id_check).
  [[nodiscard]] Status count_pixels(GLuint ids, int w, int h, std::uint32_t n, GlCounter mode);
  /// The UV sphere of the mesh geometry, built on its first use.
  void make_mesh();
  void set_camera_uniforms(const Program& p) const;

  FrameData& frame_;
  StageTimers& timers_;
  const Config& config_;
  const GlOptions& options_;
  Program impostor_, mesh_, box_, count_, shade_, splat_plan_, splat_, splat_resolve_;
  // The atomic_uint counting program: its counter array's size is compiled in, so it is built
  // on first use and rebuilt when N changes.
  Program count_atomic_;
  std::uint32_t count_atomic_n_ = 0;                                // N count_atomic_ was built for
  GLint max_fragment_counters_ = 0, max_counter_buffer_bytes_ = 0;  // driver limits of atomic_uint
  // G-buffer.
  Texture ids_tex_, depth_tex_, normal_tex_, zbuffer_;
  Framebuffer gbuffer_;
  int map_w_ = 0, map_h_ = 0;
  // The attachment-less framebuffer of the atomic_uint pass, and the empty vertex array of the
  // draws without vertex buffers (impostors, the full-screen triangle).
  Framebuffer empty_fbo_;
  VertexArray empty_vao_;
  // Nearest sampling for the id map, whatever the texture's own filters (an integer texture
  // with a linear filter is incomplete and reads as 0): bound while counting.
  Sampler nearest_;
  // The mesh geometry.
  Buffer mesh_vbo_, mesh_ibo_;
  VertexArray mesh_vao_;
  GLsizei mesh_indices_ = 0;
  Buffer image_;  // stage 9's RGBA8 pixels
  // GlGeometry::splat: nearest depth bits and id per map pixel; each sphere's rectangle, the
  // (sphere, chunk) list, its count, and the chunks the list holds (grown to the largest count).
  Buffer splat_depth_, splat_ids_, splat_rects_, splat_chunks_, splat_count_;
  std::uint32_t splat_capacity_ = 1u << 12;  // small: the tests grow it
};

}  // namespace viscd::gl
