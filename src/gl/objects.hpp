#pragma once
// RAII owners of GL objects. Each owns one name, cannot be copied, can be moved, and deletes its
// name on destruction: the context that created it must be current then (GlDetector makes its
// context current in every entry point and in its destructor).
// Shaders and passes see plain GLuint names ("views"), never the owners.

#include <epoxy/gl.h>

#include <algorithm>
#include <utility>

namespace viscd::gl {

/// One owned GL name; `Deleter::destroy(name)` deletes it.
template <class Deleter>
class Handle {
 public:
  Handle() = default;
  explicit Handle(GLuint name) : name_(name) {}
  ~Handle() { reset(); }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  Handle(Handle&& o) noexcept : name_(std::exchange(o.name_, 0)) {}
  Handle& operator=(Handle&& o) noexcept {
    if (this != &o) {
      reset();
      name_ = std::exchange(o.name_, 0);
    }
    return *this;
  }
  /// The non-owning name, for GL calls.
  [[nodiscard]] GLuint get() const { return name_; }
  [[nodiscard]] explicit operator bool() const { return name_ != 0; }
  void reset() {
    if (name_) Deleter::destroy(name_);
    name_ = 0;
  }

 private:
  GLuint name_ = 0;
};

struct BufferDeleter {
  static void destroy(GLuint n) { glDeleteBuffers(1, &n); }
};
struct TextureDeleter {
  static void destroy(GLuint n) { glDeleteTextures(1, &n); }
};
struct FramebufferDeleter {
  static void destroy(GLuint n) { glDeleteFramebuffers(1, &n); }
};
struct VertexArrayDeleter {
  static void destroy(GLuint n) { glDeleteVertexArrays(1, &n); }
};
struct SamplerDeleter {
  static void destroy(GLuint n) { glDeleteSamplers(1, &n); }
};
struct QueryDeleter {
  static void destroy(GLuint n) { glDeleteQueries(1, &n); }
};
struct ShaderDeleter {
  static void destroy(GLuint n) { glDeleteShader(n); }
};
struct ProgramDeleter {
  static void destroy(GLuint n) { glDeleteProgram(n); }
};

using Texture = Handle<TextureDeleter>;
using Framebuffer = Handle<FramebufferDeleter>;
using VertexArray = Handle<VertexArrayDeleter>;
using Query = Handle<QueryDeleter>;
using Sampler = Handle<SamplerDeleter>;
using Shader = Handle<ShaderDeleter>;
using ProgramHandle = Handle<ProgramDeleter>;

/// A GL buffer with its size in bytes. Its data store is mutable (glNamedBufferData, usage
/// GL_DYNAMIC_COPY; no glBufferStorage): `reserve` re-specifies it with a larger size on demand,
/// and the contents are not kept.
class Buffer {
 public:
  Buffer() = default;
  /// Makes sure the buffer holds at least `bytes` (at least 16, a multiple of 16); reallocates
  /// when smaller.
  void reserve(GLsizeiptr bytes) {
    if (bytes < 16) bytes = 16;
    if (handle_ && bytes <= size_) return;
    if (!handle_) {
      GLuint n = 0;
      glCreateBuffers(1, &n);
      handle_ = Handle<BufferDeleter>(n);
    }
    // Grow geometrically so that slowly growing scenes reallocate rarely, in whole 16 bytes, so
    // that clears and views of any element size (glClearNamedBufferSubData, vec4) fit the size.
    const GLsizeiptr wanted = size_ ? std::max(bytes, size_ + size_ / 2) : bytes;
    const GLsizeiptr grown = (wanted + 15) / 16 * 16;
    glNamedBufferData(handle_.get(), grown, nullptr, GL_DYNAMIC_COPY);
    size_ = grown;
  }
  [[nodiscard]] GLuint get() const { return handle_.get(); }
  [[nodiscard]] GLsizeiptr size() const { return size_; }
  /// Binds the whole buffer to an indexed SSBO binding point.
  void bind_storage(GLuint binding) const { glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding, handle_.get()); }

 private:
  Handle<BufferDeleter> handle_;
  GLsizeiptr size_ = 0;
};

}  // namespace viscd::gl
