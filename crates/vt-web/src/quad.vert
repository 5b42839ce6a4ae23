#version 300 es
// One triangle pair covering the frame buffer; every pass is a fragment shader.
in vec2 pos;
void main() { gl_Position = vec4(pos, 0.0, 1.0); }
