#pragma once
// The backend's shaders, embedded at build time (src/gl/CMakeLists.txt): each is the file in
// src/gl/shaders with shared/layout.h inlined, exactly the text glslangValidator checked.

#include <span>
#include <string_view>

namespace viscd::gl {

struct ShaderSource {
  std::string_view name;  ///< file name, e.g. "morton.comp"
  std::string_view text;  ///< GLSL source starting with #version
};

/// Every embedded shader (generated shader_sources.cpp).
[[nodiscard]] std::span<const ShaderSource> shader_sources();

/// The source of a shader by file name; empty when there is none.
[[nodiscard]] inline std::string_view find_shader(std::string_view name) {
  for (const ShaderSource& s : shader_sources())
    if (s.name == name) return s.text;
  return {};
}

}  // namespace viscd::gl
