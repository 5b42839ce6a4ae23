#version 300 es
// Shared by the fragment shaders (prepended by the player): vt's sampler and rounding.
precision highp float;
precision highp int;
precision highp sampler2D;
precision highp isampler2D;

// The output pixel (x, y) of the frame: pixel centres at integers, row 0 first (frame buffers
// hold the image top row at y = 0; only the final pass to the canvas flips).
vec2 pixel() { return gl_FragCoord.xy - 0.5; }

// H^-1 applied to a pixel, the renderer's division mapping: rows of H^-1 are m[0], m[1], m[2].
vec2 mapInv(mat3 m, vec2 p) {
  vec3 v = vec3(p, 1.0);
  return vec2(dot(m[0], v), dot(m[1], v)) / dot(m[2], v);
}

bool finite2(vec2 s) { return !(isnan(s.x) || isnan(s.y) || isinf(s.x) || isinf(s.y)); }

// vt's INSIDE: -0.5 <= x < w - 0.5 (and y).
bool inside(vec2 s, ivec2 size) {
  return s.x >= -0.5 && s.y >= -0.5 && s.x < float(size.x) - 0.5 && s.y < float(size.y) - 0.5;
}

vec3 tap(sampler2D t, ivec2 i, ivec2 size) {
  return texelFetch(t, clamp(i, ivec2(0), size - 1), 0).rgb * 255.0;
}

// vt's sampler with replicated edges: the coordinate clamped to [-1, size], then exact bilinear
// (top + (bottom - top) fy) or nearest (round half to even).
vec3 sampleRgb(sampler2D t, vec2 s, ivec2 size, bool nearest) {
  vec2 c = clamp(s, vec2(-1.0), vec2(size));
  if (nearest) return tap(t, ivec2(roundEven(c)), size);
  vec2 b = floor(c);
  vec2 f = c - b;
  ivec2 i = ivec2(b);
  vec3 a = tap(t, i, size);
  vec3 bb = tap(t, i + ivec2(1, 0), size);
  vec3 cc = tap(t, i + ivec2(0, 1), size);
  vec3 d = tap(t, i + ivec2(1, 1), size);
  vec3 top = a + (bb - a) * f.x;
  vec3 bottom = cc + (d - cc) * f.x;
  return top + (bottom - top) * f.y;
}

// vt's round_u8: (v + 0.5) truncated, saturating.
vec3 roundU8(vec3 v) { return clamp(floor(v + 0.5), 0.0, 255.0); }
