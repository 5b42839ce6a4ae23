// The object (or dynamic region) of one frame over the frame (vt_core::render's composite): the
// output pixel mapped by H^-1 into the frame's box, colour sampled bilinearly from object pixels
// only (mask-weighted, kept where the coverage is >= 0.5; nearest: the nearest pixel must be
// object), divided by the view's gain against the exposure at q; the view's dynamic-region alpha
// at the nearest source pixel scales the opacity where it is set. Written with blending (alpha,
// 1 - alpha).
uniform sampler2D rgb;
// Or the picture as I420 planes (yuv set): BT.601 limited range, each chroma sample for its 2x2
// block (vt's own 4:2:0 conversion, so the store's frames come back closest: 52 dB on a tree
// frame, against 45.8 bilinear; the export's box starts at even coordinates to keep the blocks).
uniform bool yuv;
uniform sampler2D yPlane;
uniform sampler2D uPlane;
uniform sampler2D vPlane;
uniform ivec2 ySize;
uniform sampler2D mask;
uniform sampler2D dyn;
uniform bool hasDyn;
uniform mat3 h;
uniform vec4 box;
// Where the rgb texture's texel (0, 0) lies in the view (the frame's box, or a video's union box).
uniform ivec2 rgbOrigin;
uniform vec3 gain;
uniform float alpha;
uniform bool nearest;
uniform ivec2 dynSize;
out vec4 color;

float plane(sampler2D t, ivec2 i, ivec2 size) {
  return texelFetch(t, clamp(i, ivec2(0), size - 1), 0).r * 255.0;
}

vec3 fromYuv(ivec2 l) {
  ivec2 cs = (ySize + 1) / 2;
  float u = plane(uPlane, l / 2, cs) - 128.0;
  float v = plane(vPlane, l / 2, cs) - 128.0;
  float y = (plane(yPlane, l, ySize) - 16.0) * (255.0 / 219.0);
  return clamp(vec3(y + 1.596027 * v, y - 0.391762 * u - 0.812968 * v, y + 2.017232 * u), 0.0, 255.0);
}

bool object(ivec2 i, out vec3 c) {
  ivec2 l = i - ivec2(box.xy);
  if (l.x < 0 || l.y < 0 || l.x >= int(box.z) || l.y >= int(box.w)) return false;
  if (texelFetch(mask, l, 0).r < 0.5) return false;
  c = yuv ? fromYuv(i - rgbOrigin) : texelFetch(rgb, i - rgbOrigin, 0).rgb * 255.0;
  return true;
}

void main() {
  vec2 p = pixel();
  vec3 m = vec3(p, 1.0);
  float w = dot(h[2], m);
  if (w == 0.0) discard;
  vec2 s = vec2(dot(h[0], m), dot(h[1], m)) / w;
  if (!finite2(s) || s.x < box.x - 1.0 || s.y < box.y - 1.0 || s.x > box.x + box.z
      || s.y > box.y + box.w) discard;
  vec3 colour = vec3(0.0);
  if (nearest) {
    if (!object(ivec2(roundEven(s)), colour)) discard;
  } else {
    vec2 b = floor(s);
    vec2 f = s - b;
    ivec2 i = ivec2(b);
    float cover = 0.0;
    vec3 c;
    float wt = (1.0 - f.x) * (1.0 - f.y);
    if (object(i, c)) { cover += wt; colour += wt * c; }
    wt = f.x * (1.0 - f.y);
    if (object(i + ivec2(1, 0), c)) { cover += wt; colour += wt * c; }
    wt = (1.0 - f.x) * f.y;
    if (object(i + ivec2(0, 1), c)) { cover += wt; colour += wt * c; }
    wt = f.x * f.y;
    if (object(i + ivec2(1, 1), c)) { cover += wt; colour += wt * c; }
    if (cover < 0.5) discard;
    colour /= cover;
  }
  float a = alpha;
  if (hasDyn) {
    ivec2 at = clamp(ivec2(roundEven(s)), ivec2(0), dynSize - 1);
    float d = floor(texelFetch(dyn, at, 0).r * 255.0 + 0.5);
    if (d > 0.0) a = alpha * d / 255.0;
  }
  color = vec4(clamp(colour / gain / 255.0, 0.0, 1.0), a);
}
