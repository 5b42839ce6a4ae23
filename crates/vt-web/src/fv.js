// vt fv export: System B's model in the browser, rendered by vt fv render's default method in
// WebGL2 passes: the voxel model's surface splatted as vt_fv::render::render_rough splats it,
// trimmed to the silhouettes and the depth maps' free space (clip_to_hull, clip_to_free_space),
// the photos projected onto it as vt_fv::texture::texture_view projects them (the references
// chosen and faded as fading_references chooses them, each seen only where its own splat render
// puts no surface in front, unstructured-lumigraph weights, the depth refined where they agree,
// holes filled by push-pull, softened where they disagree) and the outline's soft alpha over the
// background (vt_fv::composite). Drag to orbit, wheel to zoom, C to show the photos' cameras.
(() => {
  'use strict';
  const S = window.vtFvScene;
  const status = document.getElementById('status');
  const canvas = document.getElementById('view');
  const W = S.width;
  const H = S.height;
  const N = S.cams.length;
  const T = S.texture;
  const MAX_REFS = 16;
  const FAR = 1e30;
  const payloads = { photo: [], voxels: null };
  window.vtFvPayload = (kind, key, data) => {
    if (kind === 'photo') payloads.photo[key] = data;
    else payloads[kind] = data;
  };
  canvas.width = W;
  canvas.height = H;
  const gl = canvas.getContext('webgl2', { antialias: false, premultipliedAlpha: false, preserveDrawingBuffer: true });

  window.vt = { ready: false, error: null, drawn: 0, renderMs: 0, references: [] };

  // ---- small linear algebra (row-major 3x3 as arrays of 9) -----------------------------------
  const mul3 = (a, b) => {
    const o = new Array(9).fill(0);
    for (let i = 0; i < 3; i++) for (let j = 0; j < 3; j++) for (let k = 0; k < 3; k++) o[3 * i + j] += a[3 * i + k] * b[3 * k + j];
    return o;
  };
  const mulv = (a, v) => [0, 1, 2].map((i) => a[3 * i] * v[0] + a[3 * i + 1] * v[1] + a[3 * i + 2] * v[2]);
  const tr = (a) => [a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8]];
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
  const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const norm = (a) => Math.sqrt(dot(a, a));
  const unit = (a) => scale(a, 1 / (norm(a) || 1));
  const angle = (a, b) => Math.atan2(norm(cross(a, b)), dot(a, b));
  const inv3 = (m) => {
    const [a, b, c, d, e, f, g, h, i] = m;
    const A = e * i - f * h;
    const B = -(d * i - f * g);
    const C = d * h - e * g;
    const det = a * A + b * B + c * C;
    return [A, -(b * i - c * h), b * f - c * e, B, a * i - c * g, -(a * f - c * d), C, -(a * h - b * g), a * e - b * d].map((x) => x / det);
  };
  // Rotation by `a` radians about the unit axis `k` (Rodrigues).
  const rotation = (k, a) => {
    const [x, y, z] = k;
    const c = Math.cos(a);
    const s = Math.sin(a);
    const t = 1 - c;
    return [t * x * x + c, t * x * y - s * z, t * x * z + s * y, t * x * y + s * z, t * y * y + c, t * y * z - s * x, t * x * z - s * y, t * y * z + s * x, t * z * z + c];
  };
  const centreOf = (cam) => scale(mulv(tr(cam.r), cam.t), -1);
  const projection = (cam) => {
    const kr = mul3(cam.k, cam.r);
    const kt = mulv(cam.k, cam.t);
    return [kr[0], kr[1], kr[2], kt[0], kr[3], kr[4], kr[5], kt[1], kr[6], kr[7], kr[8], kt[2]];
  };

  // ---- the references of a view (vt_fv::texture::fading_references) -------------------------
  function samePose(a, b) {
    const ca = centreOf(a);
    const cb = centreOf(b);
    const s = Math.max(norm(ca), norm(cb), 1e-3);
    const fa = [a.r[6], a.r[7], a.r[8]];
    const fb = [b.r[6], b.r[7], b.r[8]];
    return norm(sub(ca, cb)) <= 1e-6 * s && angle(fa, fb) <= 1e-6;
  }
  function nearest(cam, n) {
    const d = unit(sub(centreOf(cam), S.centre));
    const order = S.cams.map((c, i) => [-dot(unit(sub(centreOf(c), S.centre)), d), i]);
    order.sort((a, b) => a[0] - b[0] || a[1] - b[1]);
    const chosen = [];
    for (const [, i] of order) {
      if (chosen.length === n) break;
      if (!chosen.some((j) => samePose(S.cams[i], S.cams[j]))) chosen.push(i);
    }
    return chosen;
  }
  function fadingReferences(cam) {
    const d = unit(sub(centreOf(cam), S.centre));
    const all = nearest(cam, N);
    const ang = (i) => angle(unit(sub(centreOf(S.cams[i]), S.centre)), d);
    const next = T.references + 1 < all.length ? ang(all[T.references + 1]) : Math.PI;
    const limit = Math.max(next, T.reach);
    let chosen = [];
    let fade = [];
    for (const i of all.slice(0, MAX_REFS)) {
      const f = limit > 0 ? Math.max(1 - ang(i) / limit, 0) : 1;
      if (f <= 0) break;
      chosen.push(i);
      fade.push(f);
    }
    if (chosen.length === 0) {
      chosen = all.slice(0, T.references + 1);
      fade = chosen.map(() => 1);
    }
    return { chosen, fade };
  }

  // ---- GL helpers -------------------------------------------------------------------------
  function shader(type, src) {
    const s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error('shader: ' + gl.getShaderInfoLog(s));
    return s;
  }
  function program(vs, fs) {
    const p = gl.createProgram();
    gl.attachShader(p, shader(gl.VERTEX_SHADER, vs));
    gl.attachShader(p, shader(gl.FRAGMENT_SHADER, fs));
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error('program: ' + gl.getProgramInfoLog(p));
    const u = {};
    const n = gl.getProgramParameter(p, gl.ACTIVE_UNIFORMS);
    for (let i = 0; i < n; i++) {
      const name = gl.getActiveUniform(p, i).name.replace(/\[0\]$/, '');
      u[name] = gl.getUniformLocation(p, name);
    }
    return { p, u };
  }
  // A texture with immutable storage of `size` ([w, h] for TEXTURE_2D, [w, h, depth] for the
  // others), edges clamped, sampled by `filter`.
  function storage(kind, internal, size, filter = gl.NEAREST) {
    const t = gl.createTexture();
    gl.bindTexture(kind, t);
    if (kind === gl.TEXTURE_2D) gl.texStorage2D(kind, 1, internal, size[0], size[1]);
    else gl.texStorage3D(kind, 1, internal, size[0], size[1], size[2]);
    for (const [k, v] of [[gl.TEXTURE_MIN_FILTER, filter], [gl.TEXTURE_MAG_FILTER, filter], [gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE], [gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE]]) gl.texParameteri(kind, k, v);
    return t;
  }
  // A render target's texture at the photos' size.
  const tex2d = (internal) => storage(gl.TEXTURE_2D, internal, [W, H]);
  function target(textures, depth) {
    const fb = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
    textures.forEach((t, i) => gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0 + i, gl.TEXTURE_2D, t, 0));
    if (depth) gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, depth);
    gl.drawBuffers(textures.map((_, i) => gl.COLOR_ATTACHMENT0 + i));
    if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) throw new Error('this browser cannot render to float textures');
    return fb;
  }
  const { bytes, loadScript } = vtUtil;

  // ---- shaders ------------------------------------------------------------------------------
  // Splats: a surface voxel as a square of side scale * f * size / z around its projection
  // (at least a pixel), depth-tested on its centre's depth; writes colour and camera depth.
  const SPLAT_VS = `#version 300 es
  in vec3 pos; in vec3 col;
  uniform mat3 K; uniform mat3 R; uniform vec3 t; uniform float focal; uniform float side;
  uniform vec2 size; uniform vec2 range;
  out vec3 vcol; flat out float vz;
  void main() {
    vec3 c = R * pos + t;
    vcol = col; vz = c.z;
    if (c.z <= 1e-9) { gl_Position = vec4(2.0, 2.0, 2.0, 1.0); gl_PointSize = 1.0; return; }
    vec3 p = K * c;
    vec2 uv = p.xy / p.z;
    vec2 ndc = (uv + 0.5) / size * 2.0 - 1.0;
    float zn = clamp((c.z - range.x) / (range.y - range.x), 0.0, 1.0) * 2.0 - 1.0;
    gl_Position = vec4(ndc, zn, 1.0);
    gl_PointSize = max(side * focal / c.z, 1.0);
  }`;
  const SPLAT_FS = `#version 300 es
  precision highp float;
  in vec3 vcol; flat in float vz;
  layout(location = 0) out vec4 colour; layout(location = 1) out vec4 depth;
  void main() { colour = vec4(vcol, 1.0); depth = vec4(vz, 0.0, 0.0, 0.0); }`;
  const QUAD_VS = `#version 300 es
  void main() { vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0); gl_Position = vec4(p, 0.0, 1.0); }`;
  // What the per-pixel passes share: the references (projection rows, centres, fades, layers),
  // whether one sees a world point (in front of its own splat depth there, within tol), and
  // its bilinear sample (vt_fv::texture's `seen` and `bilinear`).
  const REFS_GLSL = `#version 300 es
  precision highp float; precision highp int; precision highp sampler2DArray;
  uniform sampler2DArray photos; uniform sampler2DArray refdepth;
  uniform mat3 A; uniform vec3 own; uniform int count;
  uniform vec4 P0[${MAX_REFS}]; uniform vec4 P1[${MAX_REFS}]; uniform vec4 P2[${MAX_REFS}];
  uniform vec3 centres[${MAX_REFS}]; uniform float fades[${MAX_REFS}]; uniform int layers[${MAX_REFS}];
  uniform float tol; uniform vec2 size;
  vec3 pointAt(ivec2 px, float d) { return A * vec3(vec2(px), 1.0) * d + own; }
  bool sees(int k, vec3 pt, out vec2 uv) {
    vec4 x = vec4(pt, 1.0);
    vec3 q = vec3(dot(P0[k], x), dot(P1[k], x), dot(P2[k], x));
    uv = vec2(-1.0);
    if (q.z <= 0.0) return false;
    uv = q.xy / q.z;
    if (uv.x < 0.0 || uv.y < 0.0 || uv.x > size.x - 1.0 || uv.y > size.y - 1.0) return false;
    ivec2 ip = min(ivec2(uv + 0.5), ivec2(size) - 1);
    float rd = texelFetch(refdepth, ivec3(ip, layers[k]), 0).r;
    return rd < ${FAR / 10} && q.z <= rd + tol;
  }
  vec3 photo(int k, vec2 uv) { return texture(photos, vec3((uv + 0.5) / size, float(layers[k]))).rgb * 255.0; }
  `;
  // vt_fv::render's trims of the splat render, per pixel: to the visual hull of the silhouettes
  // (clip_to_hull: some point of the ray near the splat depth inside every photo's silhouette
  // that sees it) and past the free space the photos' depth maps prove (clip_to_free_space);
  // a pixel trimmed away is uncovered. Cameras' projections are rows of `camsTex`.
  // The photos' depth maps, one layer per camera (vt_fv::stereo::DepthMap::nearest): the depth
  // at the cell nearest a pixel, -1 where there is none or outside the map.
  const MAPS_GLSL = `
  uniform sampler2DArray maps; uniform vec2 mapSize; uniform float mapStep;
  float mapDepth(int layer, vec2 uv) {
    vec2 cell = floor(uv / mapStep + 0.5);
    if (cell.x < 0.0 || cell.y < 0.0 || cell.x >= mapSize.x || cell.y >= mapSize.y) return -1.0;
    return texelFetch(maps, ivec3(ivec2(cell), layer), 0).r;
  }
  `;
  const CLIP_FS = `#version 300 es
  precision highp float; precision highp int; precision highp sampler2DArray; precision highp sampler3D;
  uniform sampler2D depth; uniform sampler2D rough; uniform sampler2D camsTex; uniform int ncams;
  uniform sampler2DArray sils; uniform sampler3D occ;
  uniform mat3 A; uniform vec3 own; uniform vec2 size;
  uniform float before; uniform float behind; uniform float stepSize; uniform float voxel;
  uniform int depthOn; uniform float margin; uniform float protect; uniform int through;
  uniform float vmin; uniform vec3 gmin; uniform vec3 gmax; uniform ivec3 dims;
  ${MAPS_GLSL}
  layout(location = 0) out vec4 outDepth; layout(location = 1) out vec4 outRough;
  vec3 proj(int k, vec3 x) {
    vec4 X = vec4(x, 1.0);
    return vec3(dot(texelFetch(camsTex, ivec2(0, k), 0), X), dot(texelFetch(camsTex, ivec2(1, k), 0), X), dot(texelFetch(camsTex, ivec2(2, k), 0), X));
  }
  bool insideHull(vec3 x) {
    for (int k = 0; k < 1024; k++) {
      if (k >= ncams) break;
      vec3 q = proj(k, x);
      if (q.z <= 0.0) continue;
      vec2 uv = floor(q.xy / q.z + 0.5);
      if (uv.x < 0.0 || uv.y < 0.0 || uv.x >= size.x || uv.y >= size.y) continue;
      if (texelFetch(sils, ivec3(ivec2(uv), k), 0).r < 0.5) return false;
    }
    return true;
  }
  bool freeAt(vec3 x) {
    int th = 0;
    for (int k = 0; k < 1024; k++) {
      if (k >= ncams) break;
      vec3 q = proj(k, x);
      if (q.z <= 0.0) continue;
      vec2 uv = q.xy / q.z;
      vec2 ui = floor(uv + 0.5);
      if (ui.x < 0.0 || ui.y < 0.0 || ui.x >= size.x || ui.y >= size.y) continue;
      if (texelFetch(sils, ivec3(ivec2(ui), k), 0).r < 0.5) { th += through; continue; }
      float d = mapDepth(k, uv);
      if (d < 0.0) continue;
      if (abs(d - q.z) <= protect * vmin) return false;
      if (d > q.z + margin * vmin) th += 1;
    }
    return th >= through;
  }
  bool occupied(vec3 p) {
    vec3 f = (p - gmin) / ((gmax - gmin) / vec3(dims));
    if (f.x < 0.0 || f.y < 0.0 || f.z < 0.0 || f.x >= float(dims.x) || f.y >= float(dims.y) || f.z >= float(dims.z)) return false;
    return texelFetch(occ, ivec3(f), 0).r > 0.5;
  }
  void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    float d = texelFetch(depth, px, 0).r;
    vec4 colour = texelFetch(rough, px, 0);
    outDepth = vec4(${FAR}); outRough = vec4(0.0);
    if (d >= ${FAR / 10}) return;
    vec3 ray = A * vec3(vec2(px), 1.0);
    int steps = int(floor((before + behind) / max(stepSize, 1e-3) + 0.5));
    bool keep = false;
    for (int s = 0; s <= 4096; s++) {
      if (s > steps) break;
      float t = d + (float(s) * stepSize - before) * voxel;
      if (t > 0.0 && insideHull(ray * t + own)) { keep = true; break; }
    }
    if (!keep) return;
    if (depthOn == 1 && freeAt(own + ray * d)) {
      float len = length(ray);
      float behindD = d + 0.5 * vmin / len;
      // The ray's stretch inside the grid's box (Aabb::ray_span), from just behind d on.
      float t0 = 0.0; float t1 = 3.0e38;
      for (int k = 0; k < 3; k++) {
        if (abs(ray[k]) < 1e-12) {
          if (own[k] < gmin[k] || own[k] > gmax[k]) return;
          continue;
        }
        float a = (gmin[k] - own[k]) / ray[k]; float c = (gmax[k] - own[k]) / ray[k];
        t0 = max(t0, min(a, c)); t1 = min(t1, max(a, c));
      }
      if (t0 > t1) return;
      t0 = max(t0, behindD);
      float dt = 0.5 * vmin / len;
      int n = t1 >= t0 ? int((t1 - t0) / dt) + 1 : 0;
      float found = -1.0;
      for (int k = 0; k < 100000; k++) {
        if (k >= n) break;
        float t = t0 + float(k) * dt;
        vec3 p = own + ray * t;
        if (occupied(p) && !freeAt(p)) { found = t; break; }
      }
      if (found < 0.0) return;
      d = found;
    }
    outDepth = vec4(d);
    outRough = colour;
  }`;
  // The splat depth box-filtered over the covered pixels (texture_view's smooth_depth).
  const SMOOTH_FS = `#version 300 es
  precision highp float;
  uniform sampler2D depth; uniform int radius; uniform vec2 size;
  out vec4 outDepth;
  void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    if (texelFetch(depth, px, 0).r >= ${FAR / 10}) { outDepth = vec4(${FAR}); return; }
    float sum = 0.0; float n = 0.0;
    for (int dy = -radius; dy <= radius; dy++) for (int dx = -radius; dx <= radius; dx++) {
      ivec2 q = px + ivec2(dx, dy);
      if (q.x < 0 || q.y < 0 || q.x >= int(size.x) || q.y >= int(size.y)) continue;
      float v = texelFetch(depth, q, 0).r;
      if (v < ${FAR / 10}) { sum += v; n += 1.0; }
    }
    outDepth = vec4(sum / n);
  }`;
  // One candidate depth of the refinement: the fade-weighted variance of the references'
  // colours at the point `offset` along the ray (-1 where fewer than two see it).
  const COST_FS = REFS_GLSL + `
  uniform sampler2D smoothed; uniform float offset;
  out vec4 outCost;
  void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    float d = texelFetch(smoothed, px, 0).r;
    if (d >= ${FAR / 10}) { outCost = vec4(-1.0); return; }
    vec3 pt = pointAt(px, d + offset);
    vec3 s1 = vec3(0.0); vec3 s2 = vec3(0.0); float m = 0.0; int n = 0;
    for (int k = 0; k < ${MAX_REFS}; k++) {
      if (k >= count) break;
      vec2 uv;
      if (!sees(k, pt, uv)) continue;
      vec3 c = photo(k, uv);
      s1 += fades[k] * c; s2 += fades[k] * c * c; m += fades[k]; n += 1;
    }
    if (n < 2) { outCost = vec4(-1.0); return; }
    vec3 mean = s1 / m;
    vec3 v = max(s2 / m - mean * mean, 0.0);
    outCost = vec4(v.r + v.g + v.b);
  }`;
  // Per pixel the candidate whose cost, averaged over the window, is least (ties and no
  // information keep the smoothed depth).
  const PICK_FS = `#version 300 es
  precision highp float; precision highp int; precision highp sampler2DArray;
  uniform sampler2D smoothed; uniform sampler2DArray costs; uniform int sweep; uniform int radius;
  uniform float stepSize; uniform vec2 size;
  out vec4 outDepth;
  void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    float d = texelFetch(smoothed, px, 0).r;
    if (d >= ${FAR / 10}) { outDepth = vec4(${FAR}); return; }
    float best = 3.0e38; int bi = sweep;
    for (int c = 0; c <= 2 * sweep; c++) {
      float sum = 0.0; float n = 0.0;
      for (int dy = -radius; dy <= radius; dy++) for (int dx = -radius; dx <= radius; dx++) {
        ivec2 q = px + ivec2(dx, dy);
        if (q.x < 0 || q.y < 0 || q.x >= int(size.x) || q.y >= int(size.y)) continue;
        float v = texelFetch(costs, ivec3(q, c), 0).r;
        if (v >= 0.0) { sum += v; n += 1.0; }
      }
      if (n == 0.0) continue;
      float v = sum / n;
      if (v < best || (v == best && abs(c - sweep) < abs(bi - sweep))) { best = v; bi = c; }
    }
    outDepth = vec4(d + float(bi - sweep) * stepSize);
  }`;
  // Per pixel: the refined depth's surface point projected into the references that see it,
  // blended; alpha = how much to soften (texture_view).
  const TEXTURE_FS = REFS_GLSL + `
  uniform sampler2D refined; uniform sampler2D rough;
  uniform float eps2; uniform float agree; uniform float fullFade;
  ${MAPS_GLSL}
  uniform int snapSteps; uniform float snapStep;
  out vec4 outColour;
  // Reference k's camera depth of the ray's point at d less its depth map's there (texture.rs's
  // snapped: the nearest cell); ok false where the map has none.
  float gapAt(int k, ivec2 px, float d, out bool ok) {
    vec4 x = vec4(pointAt(px, d), 1.0);
    vec3 q = vec3(dot(P0[k], x), dot(P1[k], x), dot(P2[k], x));
    ok = false;
    if (q.z <= 0.0) return 0.0;
    float z = mapDepth(layers[k], q.xy / q.z);
    if (z < 0.0) return 0.0;
    ok = true;
    return q.z - z;
  }
  // texture.rs's snapped: uv moved to where the ray meets reference k's depth map, the crossing
  // nearest d searched outward (the far side first), within snapSteps steps each way.
  void snapped(int k, ivec2 px, float d, inout vec2 uv) {
    bool ok0; float g0 = gapAt(k, px, d, ok0);
    bool okU = ok0; bool okD = ok0; float gU = g0; float gD = g0;
    for (int j = 1; j <= 4096; j++) {
      if (j > snapSteps) break;
      for (int s = 0; s < 2; s++) {
        float dir = s == 0 ? 1.0 : -1.0;
        bool ok; float g = gapAt(k, px, d + dir * float(j) * snapStep, ok);
        bool lok = s == 0 ? okU : okD; float lg = s == 0 ? gU : gD;
        if (lok && ok && ((lg < 0.0) != (g < 0.0))) {
          float t = lg / (lg - g);
          vec4 x = vec4(pointAt(px, d + dir * (float(j - 1) + t) * snapStep), 1.0);
          vec3 q = vec3(dot(P0[k], x), dot(P1[k], x), dot(P2[k], x));
          vec2 u = q.xy / q.z;
          if (u.x >= 0.0 && u.y >= 0.0 && u.x <= size.x - 1.0 && u.y <= size.y - 1.0) uv = u;
          return;
        }
        if (s == 0) { okU = ok; gU = g; } else { okD = ok; gD = g; }
      }
    }
  }
  void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    float d = texelFetch(refined, px, 0).r;
    if (d >= ${FAR / 10}) { outColour = vec4(0.0); return; }
    vec3 pt = pointAt(px, d);
    vec3 view = normalize(own - pt);
    vec3 acc = vec3(0.0); vec3 sq = vec3(0.0); float wsum = 0.0; int m = 0;
    float top0 = 0.0; float top1 = 0.0;
    for (int k = 0; k < ${MAX_REFS}; k++) {
      if (k >= count) break;
      vec2 uv;
      if (!sees(k, pt, uv)) continue;
      vec3 r = normalize(centres[k] - pt);
      float a = atan(length(cross(view, r)), dot(view, r));
      float wt = fades[k] / (a * a + eps2);
      float f = fades[k];
      if (f > top0) { top1 = top0; top0 = f; } else if (f > top1) { top1 = f; }
      if (snapSteps > 0) snapped(k, px, d, uv);
      vec3 c = photo(k, uv);
      acc += wt * c; sq += wt * c * c; wsum += wt; m += 1;
    }
    if (wsum <= 0.0) { outColour = vec4(texelFetch(rough, px, 0).rgb, 1.0); return; }
    vec3 mean = acc / wsum;
    float t = 1.0;
    if (agree > 0.0) {
      float sd = 1e30;
      if (m >= 2) { vec3 v = max(sq / wsum - mean * mean, 0.0); sd = (sqrt(v.r) + sqrt(v.g) + sqrt(v.b)) / 3.0; }
      float single = 1.0 - min(top1 / fullFade, 1.0);
      t = max(min(sd / agree, 1.0), single);
    }
    outColour = vec4(floor(mean + 0.5) / 255.0, t);
  }`;
  // The object region (texture_view's `region`): the coverage closed by a square of
  // `radius` (dilated from the depth, then eroded; pixels outside the image count for neither).
  const MORPH_FS = `#version 300 es
  precision highp float;
  uniform sampler2D src; uniform int radius; uniform int erode; uniform vec2 size;
  out vec4 outMask;
  void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    bool acc = erode == 1;
    for (int dy = -radius; dy <= radius; dy++) for (int dx = -radius; dx <= radius; dx++) {
      ivec2 q = px + ivec2(dx, dy);
      if (q.x < 0 || q.y < 0 || q.x >= int(size.x) || q.y >= int(size.y)) continue;
      float v = texelFetch(src, q, 0).r;
      bool on = erode == 1 ? v > 0.5 : v < ${FAR / 10};
      acc = erode == 1 ? (acc && on) : (acc || on);
    }
    outMask = vec4(acc ? 1.0 : 0.0);
  }`;
  // Push-pull (texture_view's hole filling): each coarser level the mean of the known texels of
  // 2x2 (alpha: known), then each level's unknown texels from the coarser one.
  const PUSH_FS = `#version 300 es
  precision highp float;
  uniform sampler2D src; uniform sampler2D depth; uniform int base; uniform ivec2 srcSize;
  out vec4 outColour;
  void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    if (base == 1) {
      // Level 0: the textured colours where the render covers.
      vec4 c = texelFetch(src, px, 0);
      outColour = texelFetch(depth, px, 0).r < ${FAR / 10} ? vec4(c.rgb * 255.0, 1.0) : vec4(0.0);
      return;
    }
    vec3 acc = vec3(0.0); float n = 0.0;
    for (int k = 0; k < 4; k++) {
      ivec2 q = 2 * px + ivec2(k & 1, k >> 1);
      if (q.x >= srcSize.x || q.y >= srcSize.y) continue;
      vec4 v = texelFetch(src, q, 0);
      if (v.a > 0.0) { acc += v.rgb; n += 1.0; }
    }
    outColour = n > 0.0 ? vec4(acc / n, 1.0) : vec4(0.0);
  }`;
  const PULL_FS = `#version 300 es
  precision highp float;
  uniform sampler2D fine; uniform sampler2D coarse;
  out vec4 outColour;
  void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 v = texelFetch(fine, px, 0);
    outColour = v.a > 0.0 ? v : texelFetch(coarse, px / 2, 0);
  }`;
  // The textured view over the object region: known colours, holes filled, the photos'
  // backdrop outside (only the softening's blur reads it); alpha the softening (1 where no
  // photo gave the colour).
  const FILL_FS = `#version 300 es
  precision highp float;
  uniform sampler2D sharp; uniform sampler2D filled; uniform sampler2D region; uniform sampler2D depth;
  uniform vec3 backdrop;
  out vec4 outColour;
  void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    if (texelFetch(region, px, 0).r < 0.5) { outColour = vec4(backdrop, 0.0); return; }
    if (texelFetch(depth, px, 0).r < ${FAR / 10}) { outColour = texelFetch(sharp, px, 0); return; }
    vec4 f = texelFetch(filled, px, 0);
    outColour = vec4(floor(f.rgb + 0.5) / 255.0, 1.0);
  }`;
  // One direction of a Gaussian blur (reflect-101 borders, as vt_core::blur).
  const BLUR_FS = `#version 300 es
  precision highp float;
  uniform sampler2D src; uniform ivec2 dir; uniform float weights[16]; uniform int radius; uniform vec2 size;
  uniform int masked;
  out vec4 outColour;
  int reflect101(int i, int n) { if (n == 1) return 0; while (i < 0 || i >= n) { if (i < 0) i = -i; if (i >= n) i = 2 * n - 2 - i; } return i; }
  void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 acc = vec4(0.0);
    for (int k = -15; k <= 15; k++) {
      if (k < -radius || k > radius) continue;
      ivec2 q = px + dir * k;
      q = ivec2(reflect101(q.x, int(size.x)), reflect101(q.y, int(size.y)));
      vec4 v = texelFetch(src, q, 0);
      // The first pass reads the images themselves: the texture outside the coverage is
      // black, the rough render is weighted by its coverage.
      if (masked == 1) v = vec4(v.a > 0.0 ? v.rgb : vec3(0.0), v.a > 0.0 ? 1.0 : 0.0);
      acc += weights[k < 0 ? -k : k] * v;
    }
    outColour = acc;
  }`;
  // The textured colours softened where the photos disagree (texture_view's last step), over
  // the background outside the object region (`depth` here: the region, 1 inside).
  const FINAL_FS = `#version 300 es
  precision highp float;
  uniform sampler2D sharp; uniform sampler2D soft; uniform sampler2D model; uniform sampler2D depth;
  uniform float consensus; uniform vec3 background;
  out vec4 outColour;
  void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    if (texelFetch(depth, px, 0).r < 0.5) { outColour = vec4(background, 1.0); return; }
    vec4 s = texelFetch(sharp, px, 0);
    vec3 c = floor(texelFetch(soft, px, 0).rgb * 255.0 + 0.5);
    vec4 m = texelFetch(model, px, 0);
    if (consensus > 0.0 && m.a > 0.02) c = (1.0 - consensus) * c + consensus * (m.rgb / m.a * 255.0);
    vec3 o = (1.0 - s.a) * s.rgb * 255.0 + s.a * c;
    outColour = vec4(floor(o + 0.5) / 255.0, 1.0);
  }`;
  // The view as vt_fv::composite shows it: the coverage as a soft alpha (the share of covered
  // pixels in each 3x3, edges replicated), the colour just outside the coverage the mean of
  // its covered neighbours, over the background.
  const COMPOSE_FS = `#version 300 es
  precision highp float;
  uniform sampler2D colour; uniform sampler2D depth; uniform vec3 background; uniform int flip; uniform vec2 size;
  out vec4 outColour;
  bool covered(ivec2 q) { return texelFetch(depth, q, 0).r < ${FAR / 10}; }
  void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    if (flip == 1) px.y = int(size.y) - 1 - px.y;
    ivec2 hi = ivec2(size) - 1;
    float n = 0.0; vec3 sum = vec3(0.0); float m = 0.0;
    for (int dy = -1; dy <= 1; dy++) for (int dx = -1; dx <= 1; dx++) {
      ivec2 q = px + ivec2(dx, dy);
      if (covered(clamp(q, ivec2(0), hi))) n += 1.0;
      if (q == clamp(q, ivec2(0), hi) && covered(q)) { sum += floor(texelFetch(colour, q, 0).rgb * 255.0 + 0.5); m += 1.0; }
    }
    float a = floor((n * 255.0 + 4.0) / 9.0);
    vec3 p = covered(px) ? floor(texelFetch(colour, px, 0).rgb * 255.0 + 0.5) : (m > 0.0 ? floor((sum + floor(m / 2.0)) / m) : vec3(0.0));
    vec3 o = floor((p * a + floor(background * 255.0 + 0.5) * (255.0 - a) + 127.0) / 255.0);
    outColour = vec4(o / 255.0, 1.0);
  }`;
  const LINE_VS = `#version 300 es
  in vec3 pos;
  uniform mat3 K; uniform mat3 R; uniform vec3 t; uniform vec2 size;
  void main() {
    vec3 c = R * pos + t;
    vec3 p = K * c;
    vec2 uv = p.xy / max(p.z, 1e-6);
    vec2 ndc = (uv + 0.5) / size * 2.0 - 1.0;
    gl_Position = c.z > 1e-6 ? vec4(ndc.x, -ndc.y, 0.0, 1.0) : vec4(2.0, 2.0, 2.0, 1.0);
  }`;
  const LINE_FS = `#version 300 es
  precision highp float; out vec4 o; void main() { o = vec4(1.0, 0.8, 0.2, 1.0); }`;

  // ---- state ----------------------------------------------------------------------------------
  let progs;
  let voxels;
  let photosTex;
  let refDepth;
  const targets = {};
  const clipTex = {};
  let lines = null;
  const view = { cam: null, showCameras: false, dirty: true };
  const radius = (() => {
    const d = sub(S.bounds.max, S.bounds.min);
    return 0.5 * norm(d);
  })();

  // Splats the model from `cam` into the bound framebuffer (colour, depth).
  function splat(cam) {
    const c = centreOf(cam);
    const dist = norm(sub(c, S.centre));
    const near = Math.max(dist - radius * 1.5, dist * 1e-4);
    const far = dist + radius * 1.5;
    const pr = progs.splat;
    gl.useProgram(pr.p);
    gl.uniformMatrix3fv(pr.u.K, true, cam.k);
    gl.uniformMatrix3fv(pr.u.R, true, cam.r);
    gl.uniform3fv(pr.u.t, cam.t);
    gl.uniform1f(pr.u.focal, 0.5 * (Math.abs(cam.k[0]) + Math.abs(cam.k[4])));
    gl.uniform1f(pr.u.side, S.splat_scale * S.voxel);
    gl.uniform2f(pr.u.size, W, H);
    gl.uniform2f(pr.u.range, near, far);
    gl.viewport(0, 0, W, H);
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LESS);
    gl.clearBufferfv(gl.COLOR, 0, [0, 0, 0, 0]);
    gl.clearBufferfv(gl.COLOR, 1, [FAR, 0, 0, 0]);
    gl.clearBufferfv(gl.DEPTH, 0, [1]);
    gl.bindVertexArray(voxels.vao);
    gl.drawArrays(gl.POINTS, 0, voxels.n);
    gl.bindVertexArray(null);
    gl.disable(gl.DEPTH_TEST);
  }

  async function load() {
    if (!gl) throw new Error('this browser has no WebGL2');
    if (!gl.getExtension('EXT_color_buffer_float')) throw new Error('this browser cannot render to float textures');
    progs = {
      splat: program(SPLAT_VS, SPLAT_FS),
      clip: program(QUAD_VS, CLIP_FS),
      smooth: program(QUAD_VS, SMOOTH_FS),
      cost: program(QUAD_VS, COST_FS),
      pick: program(QUAD_VS, PICK_FS),
      texture: program(QUAD_VS, TEXTURE_FS),
      morph: program(QUAD_VS, MORPH_FS),
      push: program(QUAD_VS, PUSH_FS),
      pull: program(QUAD_VS, PULL_FS),
      fill: program(QUAD_VS, FILL_FS),
      compose: program(QUAD_VS, COMPOSE_FS),
      blur: program(QUAD_VS, BLUR_FS),
      final: program(QUAD_VS, FINAL_FS),
      line: program(LINE_VS, LINE_FS),
    };
    status.textContent = 'loading the model';
    await loadScript('data/voxels.js');
    const v = payloads.voxels;
    const xyz = new Float32Array(bytes(v.xyz).buffer);
    const rgb = bytes(v.rgb);
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const buf = (data, loc, n, type, normalized) => {
      const b = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, b);
      gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(loc);
      gl.vertexAttribPointer(loc, n, type, normalized, 0, 0);
    };
    buf(xyz, gl.getAttribLocation(progs.splat.p, 'pos'), 3, gl.FLOAT, false);
    buf(rgb, gl.getAttribLocation(progs.splat.p, 'col'), 3, gl.UNSIGNED_BYTE, true);
    gl.bindVertexArray(null);
    voxels = { vao, n: v.n };
    payloads.voxels = null;

    // Render targets at the photos' size.
    const depthRb = gl.createRenderbuffer();
    gl.bindRenderbuffer(gl.RENDERBUFFER, depthRb);
    gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT32F, W, H);
    targets.rough = tex2d(gl.RGBA8);
    targets.depth = tex2d(gl.R32F);
    targets.splatFb = target([targets.rough, targets.depth], depthRb);
    targets.clippedDepth = tex2d(gl.R32F);
    targets.clippedRough = tex2d(gl.RGBA8);
    targets.clipFb = target([targets.clippedDepth, targets.clippedRough]);
    for (const name of ['smoothed', 'refined']) {
      targets[name] = tex2d(gl.R32F);
      targets[name + 'Fb'] = target([targets[name]]);
    }
    const layers = 2 * Math.max(T.sweep, 0) + 1;
    targets.costs = storage(gl.TEXTURE_2D_ARRAY, gl.R32F, [W, H, layers]);
    targets.costFbs = [];
    for (let c = 0; c < layers; c++) {
      const fb = gl.createFramebuffer();
      gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
      gl.framebufferTextureLayer(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, targets.costs, 0, c);
      gl.drawBuffers([gl.COLOR_ATTACHMENT0]);
      targets.costFbs.push(fb);
    }
    for (const name of ['dilated', 'region']) {
      targets[name] = tex2d(gl.R8);
      targets[name + 'Fb'] = target([targets[name]]);
    }
    // The push-pull pyramid: per level its texels and the filled ones.
    targets.levels = [];
    for (let w = W, h = H; ; w = Math.ceil(w / 2), h = Math.ceil(h / 2)) {
      const level = { w, h };
      for (const name of ['own', 'filled']) {
        const t = storage(gl.TEXTURE_2D, gl.RGBA32F, [w, h]);
        level[name] = t;
        level[name + 'Fb'] = target([t]);
      }
      targets.levels.push(level);
      if (w === 1 && h === 1) break;
    }
    for (const name of ['sharp', 'textured', 'final', 'shown']) {
      targets[name] = tex2d(gl.RGBA8);
      targets[name + 'Fb'] = target([targets[name]]);
    }
    for (const name of ['blurA', 'blurB', 'modelA', 'modelB']) {
      targets[name] = tex2d(gl.RGBA32F);
      targets[name + 'Fb'] = target([targets[name]]);
    }

    // The photos, and each photo's own splat depth (its visibility test).
    photosTex = storage(gl.TEXTURE_2D_ARRAY, gl.RGBA8, [W, H, N], gl.LINEAR);
    refDepth = storage(gl.TEXTURE_2D_ARRAY, gl.R32F, [W, H, N]);
    const layerFb = gl.createFramebuffer();
    const scratch = tex2d(gl.RGBA8);
    for (let i = 0; i < N; i++) {
      status.textContent = `loading photo ${i + 1} of ${N}`;
      await loadScript('data/photo_' + String(i).padStart(3, '0') + '.js');
      const img = await createImageBitmap(new Blob([bytes(payloads.photo[i])], { type: 'image/png' }), { premultiplyAlpha: 'none', colorSpaceConversion: 'none' });
      payloads.photo[i] = null;
      gl.bindTexture(gl.TEXTURE_2D_ARRAY, photosTex);
      gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, 0, i, W, H, 1, gl.RGBA, gl.UNSIGNED_BYTE, img);
      img.close();
      gl.bindFramebuffer(gl.FRAMEBUFFER, layerFb);
      gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, scratch, 0);
      gl.framebufferTextureLayer(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT1, refDepth, 0, i);
      gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, depthRb);
      gl.drawBuffers([gl.COLOR_ATTACHMENT0, gl.COLOR_ATTACHMENT1]);
      splat(S.cams[i]);
    }
    gl.deleteFramebuffer(layerFb);
    gl.deleteTexture(scratch);

    // vt fv render's trims: the silhouettes as it tests them, the cameras' projections, and for
    // the trim to free space the photos' depth maps and the model's occupied voxels.
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    if (S.clip) {
      status.textContent = 'loading the silhouettes';
      await loadScript('data/silhouettes.js');
      const bits = await vtUtil.inflate(bytes(payloads.silhouettes));
      payloads.silhouettes = null;
      clipTex.sils = storage(gl.TEXTURE_2D_ARRAY, gl.R8, [W, H, N]);
      const per = Math.ceil((W * H) / 8);
      for (let i = 0; i < N; i++) {
        gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, 0, i, W, H, 1, gl.RED, gl.UNSIGNED_BYTE, vtUtil.unpackBits(bits, i * per, W * H));
      }
      const rows = new Float32Array(12 * N);
      S.cams.forEach((c, k) => rows.set(projection(c), 12 * k));
      clipTex.cams = storage(gl.TEXTURE_2D, gl.RGBA32F, [3, N]);
      gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, 3, N, gl.RGBA, gl.FLOAT, rows);
    }
    if (S.maps) {
      status.textContent = 'loading the depth maps';
      await loadScript('data/depths.js');
      const [mw, mh] = S.maps;
      const raw = await vtUtil.inflate(bytes(payloads.depths.maps));
      const maps = new Float32Array(raw.buffer, raw.byteOffset, raw.byteLength / 4);
      clipTex.maps = storage(gl.TEXTURE_2D_ARRAY, gl.R32F, [mw, mh, N]);
      gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, 0, 0, mw, mh, N, gl.RED, gl.FLOAT, maps);
      const [nx, ny, nz] = S.dims;
      const occ = vtUtil.unpackBits(await vtUtil.inflate(bytes(payloads.depths.occupied)), 0, nx * ny * nz);
      payloads.depths = null;
      clipTex.occ = storage(gl.TEXTURE_3D, gl.R8, [nx, ny, nz]);
      gl.texSubImage3D(gl.TEXTURE_3D, 0, 0, 0, 0, nx, ny, nz, gl.RED, gl.UNSIGNED_BYTE, occ);
    } else {
      // Samplers the clip pass declares but does not read.
      clipTex.maps = storage(gl.TEXTURE_2D_ARRAY, gl.R32F, [1, 1, 1]);
      clipTex.occ = storage(gl.TEXTURE_3D, gl.R8, [1, 1, 1]);
    }

    // The photos' cameras as lines: the centre to the image corners at a tenth of its distance.
    const seg = [];
    for (const cam of S.cams) {
      const c = centreOf(cam);
      const a = mul3(tr(cam.r), inv3(cam.k));
      const depth = 0.15 * norm(sub(c, S.centre));
      const corners = [[0, 0], [W - 1, 0], [W - 1, H - 1], [0, H - 1]].map(([x, y]) => add(c, scale(mulv(a, [x, y, 1]), depth)));
      for (let k = 0; k < 4; k++) seg.push(c, corners[k], corners[k], corners[(k + 1) % 4]);
    }
    lines = { vao: gl.createVertexArray(), n: seg.length };
    gl.bindVertexArray(lines.vao);
    const lb = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, lb);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(seg.flat()), gl.STATIC_DRAW);
    const loc = gl.getAttribLocation(progs.line.p, 'pos');
    gl.enableVertexAttribArray(loc);
    gl.vertexAttribPointer(loc, 3, gl.FLOAT, false, 0, 0);
    gl.bindVertexArray(null);
  }

  function quad(pr, fb, textures, size) {
    gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
    gl.viewport(0, 0, size ? size[0] : W, size ? size[1] : H);
    gl.useProgram(pr.p);
    textures.forEach(([name, t, kind], unit) => {
      gl.activeTexture(gl.TEXTURE0 + unit);
      gl.bindTexture(kind || gl.TEXTURE_2D, t);
      gl.uniform1i(pr.u[name], unit);
    });
    gl.drawArrays(gl.TRIANGLES, 0, 3);
  }

  // Gaussian weights of vt_core::blur's kernel: ksize 2 ceil(3 sigma) + 1.
  function gaussian(sigma) {
    const r = Math.min(Math.ceil(3 * sigma), 15);
    const w = [];
    for (let k = 0; k <= r; k++) w.push(Math.exp(-(k * k) / (2 * sigma * sigma)));
    const total = w[0] + 2 * w.slice(1).reduce((a, b) => a + b, 0);
    return { r, w: w.map((x) => x / total).concat(new Array(16 - w.length).fill(0)) };
  }
  function blur(src, mid, midFb, out, outFb, masked) {
    const g = gaussian(T.soften_sigma);
    const pr = progs.blur;
    for (const [from, fb, dir, m] of [[src, midFb, [1, 0], masked], [mid, outFb, [0, 1], 0]]) {
      gl.useProgram(pr.p);
      gl.uniform1fv(pr.u.weights, g.w);
      gl.uniform1i(pr.u.radius, g.r);
      gl.uniform2f(pr.u.size, W, H);
      gl.uniform2i(pr.u.dir, dir[0], dir[1]);
      gl.uniform1i(pr.u.masked, m);
      quad(pr, fb, [['src', from]]);
    }
    return out;
  }

  // The new view from `cam` into targets.final; returns the references used.
  // `quick`: without the depth refinement (while the view moves).
  function render(cam, quick) {
    const t0 = performance.now();
    gl.bindFramebuffer(gl.FRAMEBUFFER, targets.splatFb);
    splat(cam);
    let depth = targets.depth;
    let rough = targets.rough;
    if (S.clip) {
      const cp = progs.clip;
      gl.useProgram(cp.p);
      gl.uniformMatrix3fv(cp.u.A, true, mul3(tr(cam.r), inv3(cam.k)));
      gl.uniform3fv(cp.u.own, centreOf(cam));
      gl.uniform2f(cp.u.size, W, H);
      gl.uniform1i(cp.u.ncams, N);
      gl.uniform1f(cp.u.before, S.clip.before);
      gl.uniform1f(cp.u.behind, S.clip.behind);
      gl.uniform1f(cp.u.stepSize, S.clip.step);
      gl.uniform1f(cp.u.voxel, S.clip.size);
      const dc = S.depth_clip;
      gl.uniform1i(cp.u.depthOn, dc ? 1 : 0);
      if (dc) {
        gl.uniform1f(cp.u.margin, dc.margin);
        gl.uniform1f(cp.u.protect, dc.protect);
        gl.uniform1i(cp.u.through, dc.through);
        gl.uniform1f(cp.u.vmin, dc.voxel);
        gl.uniform3fv(cp.u.gmin, S.bounds.min);
        gl.uniform3fv(cp.u.gmax, S.bounds.max);
        gl.uniform3iv(cp.u.dims, S.dims);
        gl.uniform2f(cp.u.mapSize, S.maps[0], S.maps[1]);
        gl.uniform1f(cp.u.mapStep, S.maps[2]);
      }
      quad(cp, targets.clipFb, [['depth', targets.depth], ['rough', targets.rough], ['camsTex', clipTex.cams], ['sils', clipTex.sils, gl.TEXTURE_2D_ARRAY], ['maps', clipTex.maps, gl.TEXTURE_2D_ARRAY], ['occ', clipTex.occ, gl.TEXTURE_3D]]);
      depth = targets.clippedDepth;
      rough = targets.clippedRough;
    }
    const { chosen, fade } = fadingReferences(cam);
    const P = [[], [], []];
    const centres = [];
    chosen.forEach((i) => {
      const p = projection(S.cams[i]);
      for (let r = 0; r < 3; r++) P[r].push(...p.slice(4 * r, 4 * r + 4));
      centres.push(...centreOf(S.cams[i]));
    });
    const pad = (a, n) => a.concat(new Array(n - a.length).fill(0));
    const references = (pr) => {
      gl.useProgram(pr.p);
      gl.uniform4fv(pr.u.P0, pad(P[0], 4 * MAX_REFS));
      gl.uniform4fv(pr.u.P1, pad(P[1], 4 * MAX_REFS));
      gl.uniform4fv(pr.u.P2, pad(P[2], 4 * MAX_REFS));
      gl.uniform3fv(pr.u.centres, pad(centres, 3 * MAX_REFS));
      gl.uniform1fv(pr.u.fades, pad(fade, MAX_REFS));
      gl.uniform1iv(pr.u.layers, pad(chosen, MAX_REFS));
      gl.uniform1i(pr.u.count, chosen.length);
      gl.uniformMatrix3fv(pr.u.A, true, mul3(tr(cam.r), inv3(cam.k)));
      gl.uniform3fv(pr.u.own, centreOf(cam));
      gl.uniform1f(pr.u.tol, T.tol);
      gl.uniform2f(pr.u.size, W, H);
    };
    const refTextures = [['photos', photosTex, gl.TEXTURE_2D_ARRAY], ['refdepth', refDepth, gl.TEXTURE_2D_ARRAY]];
    // The splat depth smoothed, then refined along each ray where the photos agree best.
    const sm = progs.smooth;
    gl.useProgram(sm.p);
    gl.uniform1i(sm.u.radius, T.depth_smooth);
    gl.uniform2f(sm.u.size, W, H);
    quad(sm, targets.smoothedFb, [['depth', depth]]);
    let refined = targets.smoothed;
    if (T.sweep > 0 && chosen.length >= 2 && !quick) {
      const cost = progs.cost;
      references(cost);
      for (let c = 0; c <= 2 * T.sweep; c++) {
        gl.uniform1f(cost.u.offset, (c - T.sweep) * T.sweep_step);
        quad(cost, targets.costFbs[c], [['smoothed', targets.smoothed], ...refTextures]);
      }
      const pick = progs.pick;
      gl.useProgram(pick.p);
      gl.uniform1i(pick.u.sweep, T.sweep);
      gl.uniform1i(pick.u.radius, T.sweep_window);
      gl.uniform1f(pick.u.stepSize, T.sweep_step);
      gl.uniform2f(pick.u.size, W, H);
      quad(pick, targets.refinedFb, [['smoothed', targets.smoothed], ['costs', targets.costs, gl.TEXTURE_2D_ARRAY]]);
      refined = targets.refined;
    }
    const pr = progs.texture;
    references(pr);
    gl.uniform1f(pr.u.eps2, T.eps * T.eps);
    gl.uniform1f(pr.u.agree, T.agree_sd);
    gl.uniform1f(pr.u.fullFade, T.full_fade);
    gl.uniform1i(pr.u.snapSteps, S.maps ? T.snap_steps : 0);
    gl.uniform1f(pr.u.snapStep, T.sweep_step);
    if (S.maps) {
      gl.uniform2f(pr.u.mapSize, S.maps[0], S.maps[1]);
      gl.uniform1f(pr.u.mapStep, S.maps[2]);
    }
    quad(pr, targets.sharpFb, [['refined', refined], ['rough', rough], ['maps', clipTex.maps, gl.TEXTURE_2D_ARRAY], ...refTextures]);
    // The object region (the coverage closed) and the holes in it filled by push-pull.
    const mp = progs.morph;
    gl.useProgram(mp.p);
    gl.uniform1i(mp.u.radius, T.fill_radius);
    gl.uniform2f(mp.u.size, W, H);
    gl.uniform1i(mp.u.erode, 0);
    quad(mp, targets.dilatedFb, [['src', depth]]);
    gl.uniform1i(mp.u.erode, 1);
    quad(mp, targets.regionFb, [['src', targets.dilated]]);
    const L = targets.levels;
    const push = progs.push;
    gl.useProgram(push.p);
    gl.uniform1i(push.u.base, 1);
    quad(push, L[0].ownFb, [['src', targets.sharp], ['depth', depth]]);
    gl.uniform1i(push.u.base, 0);
    for (let k = 1; k < L.length; k++) {
      gl.uniform2i(push.u.srcSize, L[k - 1].w, L[k - 1].h);
      quad(push, L[k].ownFb, [['src', L[k - 1].own], ['depth', depth]], [L[k].w, L[k].h]);
    }
    const pull = progs.pull;
    const last = L.length - 1;
    quad(pull, L[last].filledFb, [['fine', L[last].own], ['coarse', L[last].own]], [L[last].w, L[last].h]);
    for (let k = last - 1; k >= 0; k--) {
      quad(pull, L[k].filledFb, [['fine', L[k].own], ['coarse', L[k + 1].filled]], [L[k].w, L[k].h]);
    }
    gl.useProgram(progs.fill.p);
    gl.uniform3fv(progs.fill.u.backdrop, (T.backdrop || [0, 0, 0]).map((x) => x / 255));
    quad(progs.fill, targets.texturedFb, [['sharp', targets.sharp], ['filled', L[0].filled], ['region', targets.region], ['depth', depth]]);
    const soften = T.soften_sigma > 0;
    if (soften) {
      blur(targets.textured, targets.blurA, targets.blurAFb, targets.blurB, targets.blurBFb, 0);
      blur(rough, targets.modelA, targets.modelAFb, targets.modelB, targets.modelBFb, 1);
    }
    const fin = progs.final;
    gl.useProgram(fin.p);
    gl.uniform1f(fin.u.consensus, soften ? T.consensus : 0);
    gl.uniform3fv(fin.u.background, (S.background || [0, 0, 0]).map((x) => x / 255));
    const softTex = soften ? targets.blurB : targets.textured;
    const finals = [['sharp', targets.textured], ['soft', softTex], ['model', targets.modelB], ['depth', targets.region]];
    quad(fin, targets.finalFb, finals);
    const cp = progs.compose;
    gl.useProgram(cp.p);
    gl.uniform3fv(cp.u.background, (S.background || [0, 0, 0]).map((x) => x / 255));
    gl.uniform2f(cp.u.size, W, H);
    gl.uniform1i(cp.u.flip, 0);
    quad(cp, targets.shownFb, [['colour', targets.final], ['depth', depth]]);
    // On screen, rows flipped (the targets hold row 0 at the top, as the photos).
    gl.uniform1i(cp.u.flip, 1);
    quad(cp, null, [['colour', targets.final], ['depth', depth]]);
    if (view.showCameras) {
      const lp = progs.line;
      gl.useProgram(lp.p);
      gl.uniformMatrix3fv(lp.u.K, true, cam.k);
      gl.uniformMatrix3fv(lp.u.R, true, cam.r);
      gl.uniform3fv(lp.u.t, cam.t);
      gl.uniform2f(lp.u.size, W, H);
      gl.bindVertexArray(lines.vao);
      gl.drawArrays(gl.LINES, 0, lines.n);
      gl.bindVertexArray(null);
    }
    window.vt.renderMs = performance.now() - t0;
    window.vt.refined = !quick;
    window.vt.drawn += 1;
    window.vt.references = chosen.map((i) => S.cams[i].name);
    return chosen;
  }

  // The last view rendered, top row first (the targets hold row 0 at the top, as the photos).
  function readRgb() {
    return vtUtil.readRgb(gl, targets.shownFb, W, H);
  }

  // ---- interaction ----------------------------------------------------------------------------
  function describe() {
    const c = centreOf(view.cam);
    const d = sub(c, S.centre);
    status.textContent = `distance ${norm(d).toPrecision(3)} · photos ${window.vt.references.slice(0, T.references + 1).join(', ')} · ${window.vt.renderMs.toFixed(0)} ms`;
  }
  function setCamera(cam) {
    view.cam = { k: cam.k.slice(), r: cam.r.slice(), t: cam.t.slice() };
    view.dirty = true;
  }
  // Orbits the camera about the model's centre: `ax` radians about its own up axis, `ay` about
  // its right axis (both through the centre), from the pose `from`.
  function orbit(from, ax, ay) {
    const right = [from.r[0], from.r[1], from.r[2]];
    const up = [-from.r[3], -from.r[4], -from.r[5]];
    const q = mul3(rotation(up, -ax), rotation(right, ay));
    const c = add(S.centre, mulv(q, sub(centreOf(from), S.centre)));
    const r = mul3(from.r, tr(q));
    setCamera({ k: from.k, r, t: scale(mulv(r, c), -1) });
  }
  function zoom(factor) {
    const from = view.cam;
    const c = add(S.centre, scale(sub(centreOf(from), S.centre), factor));
    setCamera({ k: from.k, r: from.r, t: scale(mulv(from.r, c), -1) });
  }
  let drag = null;
  canvas.addEventListener('pointerdown', (e) => {
    drag = { x: e.clientX, y: e.clientY, cam: view.cam };
    canvas.setPointerCapture(e.pointerId);
    e.preventDefault();
  });
  canvas.addEventListener('pointermove', (e) => {
    if (!drag) return;
    const rect = canvas.getBoundingClientRect();
    orbit(drag.cam, ((e.clientX - drag.x) / (rect.width || 1)) * Math.PI, ((e.clientY - drag.y) / (rect.height || 1)) * Math.PI);
  });
  const endDrag = () => { drag = null; };
  canvas.addEventListener('pointerup', endDrag);
  canvas.addEventListener('pointercancel', endDrag);
  canvas.addEventListener('wheel', (e) => {
    zoom(Math.exp(Math.max(-1, Math.min(1, e.deltaY * 0.001))));
    e.preventDefault();
  }, { passive: false });
  document.addEventListener('keydown', (e) => {
    if (e.key === 'c' || e.key === 'C') { view.showCameras = !view.showCameras; view.dirty = true; }
    if (e.key === '+' || e.key === '=') zoom(0.9);
    if (e.key === '-') zoom(1 / 0.9);
    const k = parseInt(e.key, 10);
    if (k >= 1 && k <= S.views.length) setCamera(S.views[k - 1]);
  });
  const buttons = document.getElementById('views');
  S.views.forEach((cam, i) => {
    const b = document.createElement('button');
    b.textContent = String(i + 1);
    b.title = cam.name;
    b.addEventListener('click', () => setCamera(cam));
    buttons.appendChild(b);
  });
  document.getElementById('cameras').addEventListener('click', () => { view.showCameras = !view.showCameras; view.dirty = true; });

  // While a drag moves the view, frames skip the depth refinement; once it stops, the view is
  // rendered in full.
  function tick() {
    requestAnimationFrame(tick);
    if (!window.vt.ready) return;
    const moving = drag !== null;
    if (view.dirty) {
      view.dirty = false;
      view.rough = moving;
      render(view.cam, moving);
      describe();
    } else if (view.rough && !moving) {
      view.rough = false;
      render(view.cam, false);
      describe();
    }
  }

  load().then(() => {
    setCamera(S.views[0]);
    Object.assign(window.vt, {
      ready: true,
      // The camera shown now: { k, r, t } (row-major K and R, t; world to camera).
      camera: () => view.cam,
      // The view from `cam` ({ k, r, t }), or preset view i, shown and read back:
      // { rgb: base64 RGB rows top first, references: photo names }; lookMs says how long.
      look: (cam) => {
        setCamera(typeof cam === 'number' ? S.views[cam] : cam);
        view.dirty = false;
        const t0 = performance.now();
        const refs = render(view.cam, false);
        const rgb = readRgb();
        // Rendered and read back: what the view costs the GPU.
        window.vt.lookMs = performance.now() - t0;
        describe();
        return { rgb, references: refs.map((i) => S.cams[i].name) };
      },
      showCameras: (on) => { view.showCameras = on; view.dirty = true; },
      // Whether a change waits to be drawn.
      pending: () => view.dirty || view.rough,
      // The point the views turn about (the model's surface centroid).
      centre: S.centre,
    });
    requestAnimationFrame(tick);
  }).catch((e) => {
    window.vt.error = String(e && e.message ? e.message : e);
    status.textContent = 'cannot show the model: ' + window.vt.error;
  });
})();
