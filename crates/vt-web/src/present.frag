// The finished frame to the canvas, top row first.
uniform sampler2D frame;
uniform int rows;
out vec4 color;

void main() {
  ivec2 i = ivec2(gl_FragCoord.xy);
  color = vec4(texelFetch(frame, ivec2(i.x, rows - 1 - i.y), 0).rgb, 1.0);
}
