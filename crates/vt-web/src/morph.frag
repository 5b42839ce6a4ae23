// The background beyond the plane (vt_core::render's morph_blend): each output pixel is traced
// into both views (x0 = H_(p,q)^-1 z, then the fixed point x = x0 - frac u(x) along the view's
// parallax field, nearest cell), sampled bilinearly, divided by the view's gain (against q's
// exposure) and blended with weights (1 - frac, frac); one view alone where only it sees; the
// nearer surface alone where both traces converged on different ones; the converged trace
// preferred where only one converged (vt_core::parallax::morph_weights).
uniform sampler2D bg0;
uniform sampler2D bg1;
uniform isampler2D flow0;
uniform isampler2D flow1;
uniform mat3 h0;
uniform mat3 h1;
uniform vec3 gi0;
uniform vec3 gi1;
uniform float frac0;
uniform float frac1;
uniform float flowUnit;
uniform int steps;
uniform float converged2;
uniform float unconverged;
uniform vec2 toward0;
uniform vec2 toward1;
uniform float occlusion;
uniform ivec2 size;
uniform ivec2 fieldSize;
out vec4 color;

ivec2 cellOf(vec2 s) {
  return ivec2(roundEven(clamp(s, vec2(0.0), vec2(fieldSize - 1))));
}

vec2 trace(isampler2D flow, mat3 h, float frac, vec2 toward, vec2 p, out bool conv,
           out float near) {
  vec2 b = mapInv(h, p);
  vec2 s = b;
  vec2 prev = s;
  float fr = frac * flowUnit;
  for (int k = 0; k < steps; k++) {
    prev = s;
    vec2 u = vec2(texelFetch(flow, cellOf(s), 0).xy);
    s = b - u * fr;
  }
  vec2 e = s - prev;
  conv = dot(e, e) < converged2;
  near = dot(vec2(texelFetch(flow, cellOf(s), 0).xy), toward) * flowUnit;
  return s;
}

void main() {
  vec2 p = pixel();
  bool c0, c1;
  float n0, n1;
  vec2 s0 = trace(flow0, h0, frac0, toward0, p, c0, n0);
  vec2 s1 = trace(flow1, h1, frac1, toward1, p, c1, n1);
  bool i0 = inside(s0, size);
  bool i1 = inside(s1, size);
  float wa = 1.0 - frac0;
  float wb = frac0;
  if (i0 != i1) {
    wa = i0 ? 1.0 : 0.0;
    wb = i1 ? 1.0 : 0.0;
  } else if (c0 && c1 && abs(n0 - n1) > occlusion) {
    wa = n0 > n1 ? 1.0 : 0.0;
    wb = 1.0 - wa;
  } else if (c0 != c1) {
    wa *= c0 ? 1.0 : unconverged;
    wb *= c1 ? 1.0 : unconverged;
  }
  float norm = 1.0 / (wa + wb);
  vec3 va = sampleRgb(bg0, s0, size, false) * gi0;
  vec3 vb = sampleRgb(bg1, s1, size, false) * gi1;
  color = vec4(roundU8((va * wa + vb * wb) * norm) / 255.0, 1.0);
}
