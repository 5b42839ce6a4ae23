// A switch fade, crossfade or dissolve: two whole layers, (1 - alpha) old + alpha new, rounded.
uniform sampler2D old;
uniform sampler2D layer;
uniform float alpha;
out vec4 color;

void main() {
  ivec2 i = ivec2(gl_FragCoord.xy);
  vec3 o = texelFetch(old, i, 0).rgb * 255.0;
  vec3 l = texelFetch(layer, i, 0).rgb * 255.0;
  color = vec4(roundU8((1.0 - alpha) * o + alpha * l) / 255.0, 1.0);
}
