// Eq. (3): B_q from the views f and c through H_(p,q), weights (c - q, q - f) times inverse gains
// (each view's gain against the exposure at q), renormalised over the views whose sample falls
// inside their image (vt_core::render's blend_warps); where neither sees, both from their
// replicated edges.
uniform sampler2D bg0;
uniform sampler2D bg1;
uniform mat3 h0;
uniform mat3 h1;
uniform vec3 wg0;
uniform vec3 wg1;
uniform float w0;
uniform float w1;
uniform bool two;
uniform bool nearest;
uniform ivec2 size;
out vec4 color;

void main() {
  vec2 p = pixel();
  vec2 s0 = mapInv(h0, p);
  vec2 s1 = mapInv(h1, p);
  bool has0 = finite2(s0);
  bool has1 = two && finite2(s1);
  bool in0 = has0 && inside(s0, size);
  bool in1 = has1 && inside(s1, size);
  float wsIn = (in0 ? w0 : 0.0) + (in1 ? w1 : 0.0);
  float wsAll = (has0 ? w0 : 0.0) + (has1 ? w1 : 0.0);
  bool useIn = wsIn > 0.0;
  bool sel0 = useIn ? in0 : has0;
  bool sel1 = useIn ? in1 : has1;
  float ws = useIn ? wsIn : wsAll;
  vec3 acc = vec3(0.0);
  if (sel0) acc += wg0 * sampleRgb(bg0, s0, size, nearest);
  if (sel1) acc += wg1 * sampleRgb(bg1, s1, size, nearest);
  vec3 v = ws > 0.0 ? roundU8(acc / ws) : vec3(0.0);
  color = vec4(v / 255.0, 1.0);
}
