#version 450 core
// One triangle covering the viewport (vertex ids 0, 1, 2; no attributes).
void main() {
  const vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);
  gl_Position = vec4(p, 0.0, 1.0);
}
