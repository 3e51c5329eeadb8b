#pragma once
/// \file gl.hpp
/// The OpenGL 4.5 backend's own settings and factory (docs/gl.md). Available when
/// viscd is built with VISCD_ENABLE_GL (the default); the backend runs headless through EGL
/// (a GPU through EGL's device platform, e.g. NVIDIA's driver; else Mesa's surfaceless platform,
/// llvmpipe where there is no GPU). See docs/gl.md and docs/gpu.md.

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "viscd/config.hpp"
#include "viscd/detector.hpp"
#include "viscd/result.hpp"

namespace viscd {

/// How spheres are drawn into the visibility map (stage 1).
enum class GlGeometry : std::uint8_t {
  impostor,  ///< default: one camera-facing quad per sphere, ray-cast per pixel (exact silhouettes)
  mesh,      ///< the paper's instanced tessellated sphere (960 triangles, inscribed: slightly smaller)
  splat,     ///< compute shaders, no raster: each sphere's pixels ray-cast as the impostor's, nearest by
             ///< atomics (for GPUs with few graphics units, docs/gpu.md). Boxes stay cubes.
};

/// How pixels are counted per object (stage 2).
enum class GlCounter : std::uint8_t {
  ssbo,         ///< default: SSBO atomicAdd in a compute shader, any N
  atomic_uint,  ///< the paper's atomic counter array in a fragment shader; N <= GL_MAX_FRAGMENT_ATOMIC_COUNTERS
};

/// Settings of the gl backend beyond Config.
struct GlOptions {
  GlGeometry geometry = GlGeometry::impostor;
  GlCounter counter = GlCounter::ssbo;
  /// Debug context with synchronous debug output: any GL error makes detect() fail with the
  /// driver's message. Default off (on in the tests).
  bool debug = false;
  /// Pairs the pair buffer holds before its first growth. Default 65536 (512 KiB).
  std::uint32_t initial_pair_capacity = 1u << 16;
  /// Where m and the Morton layout (axis order, bits per axis, quantisation bounds) come from.
  /// false (default): from the PREVIOUS frame's active count, centre bounds, mean diameter and
  /// mu, read back with that frame's results, so the frame has no host wait before its final
  /// readback (every pass after culling is sized on the GPU from this frame's active count,
  /// through indirect dispatch). Centres outside the previous bounds clamp to the border cells: pairs stay exact
  /// (the tree is exact for any key order), only the codes and the tree's quality may differ
  /// from the cpu backend's. The first frame, and a frame whose N differs from the previous
  /// frame's or that counts pixels (a camera or the caller's map) when the previous one did not,
  /// or the other way round, use this frame's values as with true.
  /// true: one mid-frame readback of this frame's values after culling; m, the layout and the
  /// codes then equal the cpu backend's bit for bit. FrameStats::bits/layout report what was
  /// used in both modes.
  bool sync_layout = false;
  /// false (default): the detector creates a headless EGL context of its own. true: it uses the
  /// OpenGL 4.5 context current on the calling thread when it is created (an engine's, any
  /// window system), so that it can read the engine's textures (FrameInput::gl_id_texture) and
  /// the engine can read its buffers. That context must then be current whenever the detector
  /// is called or destroyed. The detector leaves GL state changed: the bound program, vertex
  /// array, framebuffer (0), viewport and depth test (after drawing a map of its own), shader
  /// storage, atomic counter and indirect-dispatch buffer bindings, texture units 0 and 1.
  /// `debug` installs no callback on a context that is not the detector's own.
  bool use_current_context = false;
};

/// Creates the gl backend: an EGL surfaceless OpenGL 4.5 core context of its own and the
/// backend's programs. Fails with a message when no such context can be created or a shader
/// does not build. The detector uses its context from the thread that calls detect(); it is
/// not thread-safe. FrameStats::stage_ms holds GPU times read one frame late (the previous
/// frame's; zero on the first frame), except `layout`, which is host time.
[[nodiscard]] Result<std::unique_ptr<Detector>> make_gl_detector(const Config& config, const GlOptions& options = {});

/// Your own visibility map, written by the G-buffer pass your renderer draws anyway (the paper's
/// setting): one more colour attachment, an R32UI texture holding object index + 1 per pixel and
/// 0 where no object is. Draw the objects as instances 0 .. N-1 in their index order, paste these
/// snippets into that pass's shaders (after #version; define VISCD_ID_LOCATION as the
/// attachment's output location before the fragment snippet), call viscd_write_id() in the
/// vertex shader's main(), and clear the attachment to 0 each frame
/// (glClearNamedFramebufferuiv). Then give the texture to the detector:
/// FrameInput::gl_id_texture, with GlOptions::use_current_context so that both share your
/// context. docs/embedding.md shows the whole loop (examples/engine_loop.cpp).
inline constexpr const char* kGlIdVertexGlsl =
    "flat out uint viscd_id;\n"
    "void viscd_write_id() { viscd_id = uint(gl_InstanceID) + 1u; }\n";
inline constexpr const char* kGlIdFragmentGlsl =
    "flat in uint viscd_id;\n"
    "layout(location = VISCD_ID_LOCATION) out uint viscd_id_out;\n"
    "#define viscd_output_id() (viscd_id_out = viscd_id)\n";
/// Creates the R32UI id texture of `width` x `height` texels (one level, nearest filtering) in
/// the OpenGL context current on this thread, for a G-buffer's id attachment; the caller owns
/// it (glDeleteTextures). Fails when no OpenGL 4.5 context is current, the size is outside
/// 1 .. kMaxMapSide (or above kMaxMapPixels), or viscd was built without VISCD_ENABLE_GL.
[[nodiscard]] Result<unsigned> make_gl_id_texture(int width, int height);

/// The OpenGL device the gl backend would run on, as "renderer | version", e.g.
/// "llvmpipe (LLVM 15.0.6, 256 bits) | 4.5 (Core Profile) Mesa 22.3.6"; fails with the reason
/// when no OpenGL 4.5 core context can be created or viscd was built without VISCD_ENABLE_GL.
/// Creates and destroys a context: call it once, not per frame.
[[nodiscard]] Result<std::string> gl_device();
/// True for Mesa's CPU renderers (llvmpipe, softpipe, swrast, lavapipe): OpenGL that runs on
/// the CPU, where the cpu backend is faster.
[[nodiscard]] bool is_software_renderer(std::string_view device);

}  // namespace viscd
