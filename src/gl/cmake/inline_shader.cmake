# Inlines `#include "shared/layout.h"` into a shader: GL drivers have no #include, so the text the
# build validates with glslangValidator is exactly the text embedded into the library.
# Usage: cmake -DIN=<shader> -DOUT=<file> -DSHADER_DIR=<src/gl/shaders> -P inline_shader.cmake
file(READ "${IN}" text)
file(READ "${SHADER_DIR}/shared/layout.h" layout)
string(REPLACE "#include \"shared/layout.h\"" "" rest "${text}")
if(rest MATCHES "#include")
  message(FATAL_ERROR "${IN}: only #include \"shared/layout.h\" is supported")
endif()
string(REPLACE "#include \"shared/layout.h\"" "${layout}" text "${text}")
file(WRITE "${OUT}" "${text}")
