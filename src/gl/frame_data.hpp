#pragma once
// The per-frame GPU data that several parts of the gl backend share: the objects, the FrameInfo
// and DispatchArgs blocks, the per-object buffers one stage leaves for the next, and what this
// frame's input decided (camera, map scale, filters). The objects are the frame's moving ones
// followed by the static set's (core's WithStatic): objects from `moving` on are static. A
// GlDetector owns one FrameData; its parts (visibility, culling, layout, broadphase, readback)
// hold it by reference, so that a buffer written by one stage is read by the next without a
// copy and without either part owning both.

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "core/shapes.hpp"
#include "core/visibility.hpp"
#include "gl/objects.hpp"
#include "gl/program.hpp"
#include "viscd/types.hpp"

namespace viscd::gl {

struct FrameData {
  // Buffers; their contents are declared in shaders/shared/layout.h.
  Buffer spheres;   ///< vec4 (x, y, z, r) per object, uploaded each frame (a box's box_proxy()); stages 1, 4, 5, 7
  Buffer boxes;     ///< Box per object in box frames, uploaded each frame; stages 1, 7, 8 and queries
  Buffer filters;   ///< uvec2 (group, mask) per object, uploaded in frames with filters; stages 3 and 8
  Buffer always;    ///< FrameInput::always_active, 4 bytes a word, uploaded in frames with flags; stage 3
  Buffer counts;    ///< uint per object: map pixels counted by stage 2, read by stage 3
  Buffer pixels;    ///< float per object: screen pixels written by stage 3, read back
  Buffer states;    ///< uint per object (ObjectState): stage 3 writes free / culled, stage 8 colliding; 9 reads
  Buffer active;    ///< uint per object in the tree: its index, ascending (stage 3 writes, 4 and 5 read)
  Buffer info;      ///< shader::FrameInfo: the frame's counts, bounds and sums
  Buffer dispatch;  ///< shader::DispatchArgs: work-group counts written on the GPU from FrameInfo.active_count

  // This frame's input, set when the frame begins (GlDetector::begin_frame; a stage test,
  // GlInspector::run_broadphase, sets has_filters alone).
  std::optional<detail::CameraRig> rig;  ///< the camera over its map; nullopt without a camera
  double pixel_scale = 1.0;              ///< screen pixels per map pixel (1 without a camera)
  bool has_pixels = false;               ///< pixels are counted (a camera, or the caller's map)
  bool has_filters = false;              ///< FrameInput::filters were given
  bool has_always = false;               ///< FrameInput::always_active was given
  bool has_boxes = false;                ///< the objects are boxes: `boxes` holds them, `spheres` their proxies
  std::uint32_t objects = 0;             ///< objects on the GPU: the moving ones, then the static ones
  std::uint32_t moving = 0;              ///< N, the frame's moving objects (the rest are static)

  /// Uploads the objects (`moving` of them the frame's): spheres into `spheres`; boxes into
  /// `boxes` and their box_proxy() into `spheres` (computed here, on the host, so that stages 4
  /// and 5 see the cpu backend's floats bit for bit). Buffers grow as needed.
  void upload_objects(const detail::Shapes& shapes, std::uint32_t moving_objects) {
    objects = static_cast<std::uint32_t>(shapes.size());
    moving = moving_objects;
    has_boxes = shapes.is_box();
    std::span<const Sphere> s = shapes.spheres;
    if (has_boxes) {
      proxies_.resize(shapes.boxes.size());
      for (std::size_t k = 0; k < proxies_.size(); ++k) proxies_[k] = detail::box_proxy(shapes.boxes[k]);
      s = proxies_;
      upload(boxes, std::as_bytes(shapes.boxes));
    }
    upload(spheres, std::as_bytes(s));
  }
  /// Dispatches `p` with the work-group count at `offset` (bytes) in `dispatch`.
  void dispatch_indirect(const Program& p, GLintptr offset) const {
    glUseProgram(p.get());
    glBindBuffer(GL_DISPATCH_INDIRECT_BUFFER, dispatch.get());
    glDispatchComputeIndirect(offset);
  }
  /// Bytes held by the buffers, for Detector::memory_bytes(). `filters` is not among them: the
  /// backend's memory figure has never counted it.
  [[nodiscard]] std::uint64_t buffer_bytes() const {
    std::uint64_t b = 0;
    for (const Buffer* buf : {&spheres, &boxes, &always, &counts, &pixels, &states, &active, &info, &dispatch})
      b += static_cast<std::uint64_t>(buf->size());
    return b;
  }

 private:
  static void upload(Buffer& buffer, std::span<const std::byte> bytes) {
    buffer.reserve(static_cast<GLsizeiptr>(bytes.size()));
    if (!bytes.empty()) glNamedBufferSubData(buffer.get(), 0, static_cast<GLsizeiptr>(bytes.size()), bytes.data());
  }

  std::vector<Sphere> proxies_;  // box frames: the proxies uploaded into `spheres`
};

}  // namespace viscd::gl
