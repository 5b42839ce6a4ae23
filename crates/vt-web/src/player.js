// vt's player in the browser: eq. (6) with the switch policy (vt_core::render::Player) and the
// renderer (vt_core::render::Renderer: eq. 3-5, gains, dynamic region, neighbour fill,
// crossfade and dissolve, background morph) in WebGL2, one fragment shader per warp. Assets
// arrive as scripts (data/*.js calling vtPayload), which load from file:// where fetch cannot.
'use strict';
(function () {
  const S = window.vtScene;
  const M = S.views.length;
  const W = S.width;
  const H = S.height;
  const P = S.params;
  const qMax = M - 1;
  const status = document.getElementById('status');
  const payloads = { background: [], dynamic: [], objects: [], parallax: [], group: {} };
  window.vtPayload = (kind, index, data) => { payloads[kind][index] = data; };

  // ---- eq. (6): the player ---------------------------------------------------------------

  // f, c and qbar of eq. (3)-(5): the right view at the 0.5 tie.
  function splitQ(q) {
    const f = Math.floor(q);
    const c = Math.ceil(q);
    return { floor: f, ceil: c, nearest: q - f < 0.5 ? f : c };
  }

  // The frame a view plays after `frame`: m + 1 after its loop's end n.
  function nextInLoop(view, frame) {
    const v = S.views[view];
    return frame === v.loop_end ? v.loop_start + 1 : frame + 1;
  }

  class Player {
    constructor() {
      this.state = null;
      this.wraps = 0;
      this.switches = 0;
      this.delayed = 0;
      this.postponed = 0;
    }

    postpone(q, pv, pj, qbar) {
      const pol = S.policy;
      if (!Number.isFinite(pol.max_seam) || Math.abs(pv - qbar) !== 1 || this.delayed >= pol.max_frames) return false;
      if (Math.abs(q - pv) > 0.5 + Math.min(Math.max(pol.max_past_tie, 0), 0.45)) return false;
      const v = S.views[pv];
      const seams = qbar > pv ? v.to_next_seam : v.to_prev_seam;
      return pj < seams.length && seams[pj] > pol.max_seam;
    }

    advance(q) {
      q = Math.min(Math.max(q, 0), qMax);
      let qbar = splitQ(q).nearest;
      if (this.state && this.state[0] !== qbar && this.postpone(q, this.state[0], this.state[1], qbar)) {
        this.delayed += 1;
        this.postponed += 1;
        qbar = this.state[0];
      } else {
        this.delayed = 0;
      }
      const v = S.views[qbar];
      let frame, step, continuation = null;
      if (!this.state) {
        frame = v.loop_start + 1;
        step = 'start';
      } else if (this.state[0] === qbar) {
        const [pv, pj] = this.state;
        if (pj === v.loop_end) {
          this.wraps += 1;
          if (pj + 1 < v.frames) continuation = [pv, pj + 1];
          frame = v.loop_start + 1;
          step = 'wrap';
        } else {
          frame = pj + 1;
          step = 'play';
        }
      } else {
        const [pv, pj] = this.state;
        let s = pj;
        let p = pv;
        while (p !== qbar) {
          const up = qbar > p;
          const table = up ? S.views[p].to_next : S.views[p].to_prev;
          const np = up ? p + 1 : p - 1;
          const t = s < table.length ? table[s] : null;
          s = t === null || t === undefined ? S.views[np].loop_start : t;
          p = np;
          this.switches += 1;
        }
        continuation = [pv, pj + 1];
        frame = s + 1;
        step = 'switch';
      }
      this.state = [qbar, frame];
      return { view: qbar, frame, step, continuation };
    }
  }

  // ---- WebGL2 ------------------------------------------------------------------------------

  const canvas = document.getElementById('video');
  canvas.width = W;
  canvas.height = H;
  const gl = canvas.getContext('webgl2', { antialias: false, depth: false, preserveDrawingBuffer: true });
  // What this browser lacks to play the page: served by `vt view`, the page then opens the
  // server's CPU-rendered stream instead (S.fallback); from disk it says what is missing.
  const missing = !gl ? 'WebGL2' : S.media === 'h264' && typeof VideoDecoder === 'undefined' ? 'WebCodecs' : null;
  if (missing && S.fallback) {
    status.textContent = `this browser has no ${missing}: opening the CPU-rendered stream`;
    window.vt = { error: null, fallback: missing };
    location.replace(S.fallback);
    return;
  }
  if (!gl) {
    status.textContent = 'this browser has no WebGL2';
    window.vt = { error: 'no WebGL2' };
    return;
  }
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  gl.pixelStorei(gl.UNPACK_COLORSPACE_CONVERSION_WEBGL, gl.NONE);
  gl.pixelStorei(gl.UNPACK_PREMULTIPLY_ALPHA_WEBGL, false);
  gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);

  function program(name) {
    const src = vtShaders.common + '\n' + vtShaders[name];
    const compile = (type, text) => {
      const sh = gl.createShader(type);
      gl.shaderSource(sh, text);
      gl.compileShader(sh);
      if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) throw new Error(name + ': ' + gl.getShaderInfoLog(sh));
      return sh;
    };
    const prog = gl.createProgram();
    gl.attachShader(prog, compile(gl.VERTEX_SHADER, vtShaders.vert));
    gl.attachShader(prog, compile(gl.FRAGMENT_SHADER, src));
    gl.bindAttribLocation(prog, 0, 'pos');
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(name + ': ' + gl.getProgramInfoLog(prog));
    const loc = {};
    const n = gl.getProgramParameter(prog, gl.ACTIVE_UNIFORMS);
    for (let i = 0; i < n; i++) {
      const u = gl.getActiveUniform(prog, i);
      loc[u.name] = gl.getUniformLocation(prog, u.name);
    }
    return { prog, loc };
  }

  const quad = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, quad);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 1, -1, -1, 1, -1, 1, 1, -1, 1, 1]), gl.STATIC_DRAW);
  gl.enableVertexAttribArray(0);
  gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);

  function texture(internal, w, h, format, type, data) {
    const t = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, t);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    if (data && !ArrayBuffer.isView(data)) {
      // An ImageBitmap or a VideoFrame.
      gl.texImage2D(gl.TEXTURE_2D, 0, internal, format, type, data);
    } else {
      gl.texImage2D(gl.TEXTURE_2D, 0, internal, w, h, 0, format, type, data);
    }
    return t;
  }

  function target() {
    const tex = texture(gl.RGBA8, W, H, gl.RGBA, gl.UNSIGNED_BYTE, null);
    const fb = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, tex, 0);
    return { tex, fb };
  }

  let progs = null;
  const targets = [target(), target(), target()];
  const tex = { video: [], background: [], dynamic: [], flow: [], rgb: [], origin: [], mask: [], boxes: [] };
  const dummy = texture(gl.RGBA8, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
  let grid = null;

  function bindTex(unit, t, kind) {
    gl.activeTexture(gl.TEXTURE0 + unit);
    gl.bindTexture(gl.TEXTURE_2D, t || dummy);
    return unit;
  }

  // H_(p,q)^-1 from the stored grid (vt's own at grid points, linear between).
  function hinv(p, q) {
    const steps = S.q_steps;
    const k = M > 1 ? q * steps : 0;
    const n = steps * (M - 1) + 1;
    let k0 = Math.floor(k);
    if (k0 >= n - 1) k0 = n - 1;
    const t = k - k0;
    const base = (p * n + k0) * 9;
    const out = new Float32Array(9);
    for (let i = 0; i < 9; i++) {
      const a = grid[base + i];
      out[i] = t > 0 ? a + (grid[base + 9 + i] - a) * t : a;
    }
    return out;
  }

  function draw(fb) {
    gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
    gl.viewport(0, 0, W, H);
    gl.drawArrays(gl.TRIANGLES, 0, 6);
  }

  // vt_core::parallax::nearer_towards: per view of pair p, the vector whose dot product with a
  // flow grows as the surface comes nearer, from the plane's motion between the views at the
  // output's centre (`ha`, `hb`: H_(p,q)^-1 of both views, rows).
  function nearerTowards(ha, hb, dirs) {
    const at = (m) => {
      const x = W / 2, y = H / 2;
      const w = m[6] * x + m[7] * y + m[8];
      return [(m[0] * x + m[1] * y + m[2]) / w, (m[3] * x + m[4] * y + m[5]) / w];
    };
    const [xa, xb] = [at(ha), at(hb)];
    const m = (xb[0] - xa[0]) * dirs[0] + (xb[1] - xa[1]) * dirs[1];
    const s = !Number.isFinite(m) || Math.abs(m) < 0.5 ? 0 : Math.sign(m);
    return [[dirs[0] * s, dirs[1] * s], [dirs[2] * s, dirs[3] * s]];
  }

  // The exposure at q: q's pair's gains interpolated in log, view p's own at q = p (as
  // vt_core's Renderer::exposure_at, in f32).
  function exposureAt(q) {
    const { floor: f, ceil: c } = splitQ(q);
    if (f === c) return S.views[f].gain;
    const t = q - f;
    return S.views[f].gain.map((g, k) =>
      Math.fround(Math.exp((1 - t) * Math.log(g) + t * Math.log(S.views[c].gain[k]))));
  }

  // View p's gain against the exposure at q: what its samples are divided by.
  function gainAt(p, q) {
    const e = exposureAt(q);
    return S.views[p].gain.map((g, k) => Math.fround(g / e[k]));
  }

  // Eq. (3), or the morph for a pair with stored parallax, into `fb`.
  function drawBackground(q, fb) {
    const { floor: f, ceil: c } = splitQ(q);
    const gi = (p) => gainAt(p, q).map((g) => 1 / g);
    gl.disable(gl.BLEND);
    const flow = f !== c ? tex.flow[f] : null;
    if (flow) {
      const { prog, loc } = progs.morph;
      gl.useProgram(prog);
      gl.uniform1i(loc.bg0, bindTex(0, tex.background[f]));
      gl.uniform1i(loc.bg1, bindTex(1, tex.background[c]));
      gl.uniform1i(loc.flow0, bindTex(2, flow.a));
      gl.uniform1i(loc.flow1, bindTex(3, flow.b));
      const [ha, hb] = [hinv(f, q), hinv(c, q)];
      gl.uniformMatrix3fv(loc.h0, false, ha);
      gl.uniformMatrix3fv(loc.h1, false, hb);
      const towards = nearerTowards(ha, hb, S.parallax[f].slice(2));
      gl.uniform2fv(loc.toward0, towards[0]);
      gl.uniform2fv(loc.toward1, towards[1]);
      gl.uniform1f(loc.occlusion, S.occlusion_px);
      gl.uniform3fv(loc.gi0, gi(f));
      gl.uniform3fv(loc.gi1, gi(c));
      gl.uniform1f(loc.frac0, q - f);
      gl.uniform1f(loc.frac1, 1 - (q - f));
      gl.uniform1f(loc.flowUnit, S.flow_unit);
      gl.uniform1i(loc.steps, S.morph_steps);
      gl.uniform1f(loc.converged2, S.converged_px * S.converged_px);
      gl.uniform1f(loc.unconverged, S.unconverged_weight);
      gl.uniform2i(loc.size, W, H);
      gl.uniform2i(loc.fieldSize, flow.w, flow.h);
    } else {
      const { prog, loc } = progs.blend;
      gl.useProgram(prog);
      const two = f !== c;
      const [w0, w1] = two ? [c - q, q - f] : [1, 0];
      gl.uniform1i(loc.bg0, bindTex(0, tex.background[f]));
      gl.uniform1i(loc.bg1, bindTex(1, tex.background[c]));
      gl.uniformMatrix3fv(loc.h0, false, hinv(f, q));
      gl.uniformMatrix3fv(loc.h1, false, hinv(c, q));
      gl.uniform3fv(loc.wg0, gi(f).map((g) => Math.fround(w0) * Math.fround(g)));
      gl.uniform3fv(loc.wg1, gi(c).map((g) => Math.fround(w1) * Math.fround(g)));
      gl.uniform1f(loc.w0, w0);
      gl.uniform1f(loc.w1, w1);
      gl.uniform1i(loc.two, two ? 1 : 0);
      gl.uniform1i(loc.nearest, P.nearest ? 1 : 0);
      gl.uniform2i(loc.size, W, H);
    }
    draw(fb);
  }

  // Frame `frame` of view `v` over `fb` at q with opacity `alpha`.
  function composite(fb, v, frame, alpha, q) {
    const box = tex.boxes[v][frame];
    if (!box || box[2] === 0 || box[3] === 0) return;
    const { prog, loc } = progs.composite;
    gl.useProgram(prog);
    gl.enable(gl.BLEND);
    gl.blendFuncSeparate(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA, gl.ZERO, gl.ONE);
    const entry = frames.get(v, frame);
    if (!entry) throw new Error(`view ${v} frame ${frame} is not loaded`);
    const pic = entry.pic;
    gl.uniform1i(loc.yuv, pic.y ? 1 : 0);
    gl.uniform1i(loc.rgb, bindTex(0, pic.rgb));
    gl.uniform1i(loc.yPlane, bindTex(3, pic.y));
    gl.uniform1i(loc.uPlane, bindTex(4, pic.u));
    gl.uniform1i(loc.vPlane, bindTex(5, pic.v));
    if (pic.y) gl.uniform2i(loc.ySize, pic.size[0], pic.size[1]);
    gl.uniform1i(loc.mask, bindTex(1, entry.mask));
    gl.uniform1i(loc.dyn, bindTex(2, tex.dynamic[v]));
    gl.uniform1i(loc.hasDyn, tex.dynamic[v] ? 1 : 0);
    gl.uniform2i(loc.dynSize, W, H);
    gl.uniformMatrix3fv(loc.h, false, hinv(v, q));
    gl.uniform4f(loc.box, box[0], box[1], box[2], box[3]);
    const origin = tex.video[v] ? tex.origin[v] : box;
    gl.uniform2i(loc.rgbOrigin, origin[0], origin[1]);
    gl.uniform3fv(loc.gain, gainAt(v, q));
    gl.uniform1f(loc.alpha, alpha);
    gl.uniform1i(loc.nearest, P.nearest ? 1 : 0);
    draw(fb);
    gl.disable(gl.BLEND);
  }

  // ---- eq. (3)-(5): the renderer ---------------------------------------------------------

  class Renderer {
    constructor() { this.blend = null; }

    nextBlend(choice) {
      const cf = P.crossfade;
      const d = P.dissolve;
      const sf = P.switch_fade;
      const b = this.blend;
      const jump = choice.step === 'wrap' || choice.step === 'switch';
      const c = choice.continuation;
      if (jump && c && cf > 0) return { type: 'fade', old: c, k: 0, len: cf, looped: false };
      if (jump && c && d > 0 && c[1] > 0) {
        return { type: 'dissolve', from: [c[0], c[1] - 1], to: [choice.view, choice.frame + d], k: 0 };
      }
      if (choice.step === 'switch' && c && sf > 0 && d === 0 && c[1] > 0) {
        return { type: 'fade', old: [c[0], nextInLoop(c[0], c[1] - 1)], k: 0, len: sf, looped: true };
      }
      if (choice.step === 'play' && b && b.type === 'fade' && b.k + 1 < b.len) {
        const j = b.looped ? nextInLoop(b.old[0], b.old[1]) : b.old[1] + 1;
        return { type: 'fade', old: [b.old[0], j], k: b.k + 1, len: b.len, looped: b.looped };
      }
      if (choice.step === 'play' && b && b.type === 'dissolve' && b.k + 1 < d && choice.view === b.to[0]) {
        return { type: 'dissolve', from: b.from, to: b.to, k: b.k + 1 };
      }
      return null;
    }

    // The other view of q's pair at the transition table's frame, where both have dynamic regions.
    fillFrame(q, view, frame) {
      if (!P.neighbour_fill) return null;
      const { floor, ceil } = splitQ(q);
      if (floor === ceil) return null;
      let other;
      if (view === floor) other = ceil;
      else if (view === ceil) other = floor;
      else return null;
      const V = S.views;
      if (!V[view].dynamic || !V[other].dynamic) return null;
      const table = other > view ? V[view].to_next : V[view].to_prev;
      const t = frame < table.length ? table[frame] : null;
      if (t === null || t === undefined) return null;
      return t < V[other].frames ? [other, t] : null;
    }

    // What rendering viewpoint q showing `choice` draws, without drawing: the blend state it
    // leaves, the shown frame, the fading one, the neighbour's fill and their opacities.
    plan(q, choice) {
      const V = S.views;
      let blend = this.nextBlend(choice);
      const view = choice.view;
      const b = blend;
      let shown = [view, choice.frame];
      let old = null;
      let alpha = 1;
      if (b && b.type === 'fade' && b.old[1] < V[b.old[0]].frames) {
        old = b.old;
        alpha = Math.fround((b.k + 1) / (b.len + 1));
      } else if (b && b.type === 'dissolve' && b.from[1] < V[b.from[0]].frames && b.to[1] < V[b.to[0]].frames) {
        shown = b.to;
        old = b.from;
        alpha = Math.fround((b.k + 1) / (P.dissolve + 1));
      } else {
        blend = null;
      }
      const fill = this.fillFrame(q, view, shown[1]);
      return { blend, shown, old, alpha, fill };
    }

    // The object frames rendering q showing `choice` draws, as [view, frame] pairs.
    needs(q, choice) {
      const { shown, old, fill } = this.plan(q, choice);
      return [shown, old, fill].filter((f) => f);
    }

    // Renders viewpoint q showing `choice` (its frames loaded: frames.ensure); returns the
    // target holding the frame.
    render(q, choice) {
      const { blend, shown, old, alpha, fill } = this.plan(q, choice);
      this.blend = blend;
      const view = choice.view;
      const fillAlpha = Math.min(2 * Math.abs(q - view), 1);
      const compositeShown = (fb) => {
        if (fill) composite(fb, fill[0], fill[1], fillAlpha, q);
        composite(fb, shown[0], shown[1], 1, q);
      };
      const [out, layer, mixed] = targets;
      drawBackground(q, out.fb);
      if (!old) {
        compositeShown(out.fb);
        return out;
      }
      drawBackground(q, layer.fb);
      compositeShown(layer.fb);
      composite(out.fb, old[0], old[1], 1, q);
      const { prog, loc } = progs.mix;
      gl.useProgram(prog);
      gl.uniform1i(loc.old, bindTex(0, out.tex));
      gl.uniform1i(loc.layer, bindTex(1, layer.tex));
      gl.uniform1f(loc.alpha, alpha);
      draw(mixed.fb);
      return mixed;
    }
  }

  // Waits until the GPU has drawn everything so far (a one-pixel read: gl.finish() may return
  // early), so frame times are real.
  const onePixel = new Uint8Array(4);
  function sync() {
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, onePixel);
  }

  function present(t) {
    const { prog, loc } = progs.present;
    gl.useProgram(prog);
    gl.uniform1i(loc.frame, bindTex(0, t.tex));
    gl.uniform1i(loc.rows, H);
    draw(null);
  }

  // The frame in `t` as RGB bytes, top row first, base64.
  function readRgb(t) {
    return vtUtil.readRgb(gl, t.fb, W, H);
  }

  // ---- loading ---------------------------------------------------------------------------

  const { bytes, loadScript, inflate } = vtUtil;


  function bitmap(data, type) {
    return createImageBitmap(new Blob([data], { type }), { premultiplyAlpha: 'none', colorSpaceConversion: 'none' });
  }

  // A decoded picture as textures: its Y, U and V planes (I420, converted to RGB in the shader
  // by BT.601 limited range, the matrix the export signals, so every browser gives the same
  // colours), or RGB converted by the browser for other layouts.
  async function planes(frame) {
    try {
      const { width: w, height: h } = frame.visibleRect;
      if (frame.format !== 'I420') {
        return { rgb: texture(gl.RGBA8, 0, 0, gl.RGBA, gl.UNSIGNED_BYTE, frame) };
      }
      const buf = new Uint8Array(frame.allocationSize());
      const layout = await frame.copyTo(buf);
      const plane = (k, pw, ph) => {
        gl.pixelStorei(gl.UNPACK_ROW_LENGTH, layout[k].stride);
        const t = texture(gl.R8, pw, ph, gl.RED, gl.UNSIGNED_BYTE, buf.subarray(layout[k].offset));
        gl.pixelStorei(gl.UNPACK_ROW_LENGTH, 0);
        return t;
      };
      const cw = Math.ceil(w / 2);
      const ch = Math.ceil(h / 2);
      return { y: plane(0, w, h), u: plane(1, cw, ch), v: plane(2, cw, ch), size: [w, h] };
    } finally {
      frame.close();
    }
  }

  const pad = (i) => String(i).padStart(3, '0');

  async function load() {
    progs = {};
    for (const name of ['blend', 'morph', 'composite', 'mix', 'present']) progs[name] = program(name);
    grid = new Float32Array(bytes(S.hinv).buffer);
    const scripts = [];
    for (let p = 0; p < M; p++) {
      scripts.push('background_' + pad(p));
      if (S.views[p].dynamic) scripts.push('dynamic_' + pad(p));
      if (p < M - 1 && S.parallax[p]) scripts.push('parallax_' + pad(p));
      scripts.push('objects_' + pad(p));
    }
    let done = 0;
    for (const name of scripts) {
      status.textContent = `loading ${name} (${done + 1} of ${scripts.length})`;
      await loadScript('data/' + name + '.js');
      done += 1;
    }
    for (let p = 0; p < M; p++) {
      const bg = await bitmap(bytes(payloads.background[p]), 'image/png');
      tex.background[p] = texture(gl.RGBA8, W, H, gl.RGBA, gl.UNSIGNED_BYTE, bg);
      bg.close();
      if (payloads.dynamic[p]) {
        const d = await bitmap(bytes(payloads.dynamic[p]), 'image/png');
        tex.dynamic[p] = texture(gl.RGBA8, W, H, gl.RGBA, gl.UNSIGNED_BYTE, d);
        d.close();
      }
      if (p < M - 1 && S.parallax[p]) {
        const [fw, fh] = S.parallax[p];
        const raw = await inflate(bytes(payloads.parallax[p]));
        const flows = new Int16Array(raw.buffer, raw.byteOffset, raw.byteLength / 2);
        const n = fw * fh * 2;
        tex.flow[p] = {
          w: fw,
          h: fh,
          a: texture(gl.RG16I, fw, fh, gl.RG_INTEGER, gl.SHORT, flows.subarray(0, n)),
          b: texture(gl.RG16I, fw, fh, gl.RG_INTEGER, gl.SHORT, flows.subarray(n, 2 * n)),
        };
      }
      const obj = payloads.objects[p];
      if (obj.video && typeof VideoDecoder === 'undefined') {
        throw new Error('this browser cannot decode the H.264 frames (no WebCodecs); export with --media jpeg');
      }
      tex.boxes[p] = obj.boxes;
      sources[p] = { groups: obj.groups, video: obj.video, loaded: [] };
      if (obj.video) {
        tex.video[p] = true;
        tex.origin[p] = [obj.video.x0, obj.video.y0];
      }
      payloads.objects[p] = null;
    }
  }

  // ---- object frames on demand -------------------------------------------------------------
  // A frame is decoded when a render needs it (its JPEG, or the H.264 group from the key frame
  // before it to the next) and kept as textures; beyond S.gpu_bytes the least recently used
  // frames are dropped (never those a render waits for).

  const sources = [];
  const frames = {
    entries: new Map(),
    loading: new Map(),
    used: 0,
    peak: 0,
    clock: 0,
    decoded: 0,
    key: (p, f) => p * 1048576 + f,
    get(p, f) {
      const e = this.entries.get(this.key(p, f));
      if (e) e.used = ++this.clock;
      return e;
    },
    // Frames never dropped: those the last render asked for, and those every unfinished
    // `ensure` waits for (the live page's and a test's may overlap; a waiter whose frames
    // another dropped would decode them again for ever under a small budget).
    pinned: new Set(),
    rendered: [],
    waiting: new Set(),
    repin() {
      this.pinned = new Set(this.rendered);
      for (const keys of this.waiting) keys.forEach((k) => this.pinned.add(k));
    },
    // Marks the frames of `list` used now and pins them as the last render's.
    pin(list) {
      this.rendered = list.map(([p, f]) => this.key(p, f));
      this.repin();
      list.forEach(([p, f]) => this.get(p, f));
    },
    // Loads every [view, frame] of `list` (and what comes with them), pinned meanwhile, and
    // pins them as the last render's; the least recently used others are dropped down to the
    // budget.
    async ensure(list) {
      const keys = list.map(([p, f]) => this.key(p, f));
      // A new render asks for these: the last render's frames may go.
      this.rendered = [];
      this.waiting.add(keys);
      this.repin();
      try {
        for (;;) {
          const missing = list.filter(([p, f]) => !this.entries.has(this.key(p, f)));
          if (missing.length === 0) break;
          // On as soon as a frame arrives: an H.264 group goes on decoding its later frames.
          await Promise.race([Promise.all(missing.map(([p, f]) => this.load(p, f))), this.stored()]);
        }
      } finally {
        this.waiting.delete(keys);
      }
      this.pin(list);
      this.trim();
    },
    // Starts loading the frames of `list` not held yet, pinning none: a prefetched frame stays
    // only while the budget has room for it beside the pinned ones.
    prefetch(list) {
      for (const [p, f] of list) {
        if (!this.entries.has(this.key(p, f))) this.load(p, f).catch(failed);
      }
    },
    ready(list) {
      return list.every(([p, f]) => this.entries.has(this.key(p, f)));
    },
    // Starts loading frame f of view p (with the rest of its H.264 group); resolves when done.
    load(p, f) {
      const src = sources[p];
      const g = groupOf(src, f);
      const k = this.key(p, src.video ? src.groups[g] : f);
      let pending = this.loading.get(k);
      if (!pending) {
        const store = (i, pic) => this.store(p, i, pic);
        pending = groupData(p, g)
          .then((data) => (src.video ? decodeGroup(p, g, data, store) : decodeJpeg(p, f, data, store)))
          .finally(() => this.loading.delete(k));
        this.loading.set(k, pending);
      }
      return pending;
    },
    // A promise resolved when the next frame is stored.
    stored() {
      if (!this.signal) {
        this.signal = new Promise((resolve) => { this.wake = resolve; });
      }
      return this.signal;
    },
    store(p, f, pic) {
      const k = this.key(p, f);
      if (this.entries.has(k)) {
        release(pic);
        return;
      }
      const [, , bw, bh] = tex.boxes[p][f];
      const n = bw * bh;
      const src = sources[p];
      const group = src.loaded[groupOf(src, f)];
      const bits = group.bits;
      const off = group.offsets[f - group.start];
      // Each frame's mask starts on a byte.
      const m = vtUtil.unpackBits(bits, off >> 3, n);
      const mask = n > 0 ? texture(gl.R8, bw, bh, gl.RED, gl.UNSIGNED_BYTE, m) : null;
      const bytes = n + (pic ? pic.bytes : 0);
      this.entries.set(k, { pic: pic || {}, mask, bytes, used: ++this.clock });
      this.used += bytes;
      this.decoded += 1;
      this.trim();
      if (this.wake) {
        const wake = this.wake;
        this.signal = null;
        this.wake = null;
        wake();
      }
    },
    trim() {
      if (this.used > S.gpu_bytes) {
        const order = [...this.entries].filter(([k]) => !this.pinned.has(k)).sort((a, b) => a[1].used - b[1].used);
        for (const [k, e] of order) {
          if (this.used <= S.gpu_bytes) break;
          release(e.pic);
          if (e.mask) gl.deleteTexture(e.mask);
          this.entries.delete(k);
          this.used -= e.bytes;
        }
      }
      this.peak = Math.max(this.peak, this.used);
    },
  };

  function release(pic) {
    if (!pic) return;
    for (const t of [pic.rgb, pic.y, pic.u, pic.v]) if (t) gl.deleteTexture(t);
  }

  // The group of view `src` that holds frame f.
  function groupOf(src, f) {
    const gs = src.groups;
    let lo = 0;
    let hi = gs.length - 1;
    while (lo < hi) {
      const mid = (lo + hi + 1) >> 1;
      if (gs[mid] <= f) lo = mid;
      else hi = mid - 1;
    }
    return lo;
  }

  // Group g of view p's object frames: its script loaded (once) and its masks inflated,
  // { start, bits, offsets (each frame's first bit), pictures (base64) }.
  function groupData(p, g) {
    const src = sources[p];
    if (!src.loaded[g]) {
      const name = 'objects_' + pad(p) + '_' + String(g).padStart(4, '0');
      src.loaded[g] = loadScript('data/' + name + '.js').then(async () => {
        const id = p + ',' + g;
        const data = payloads.group[id];
        delete payloads.group[id];
        if (!data) throw new Error(`data/${name}.js holds no frames`);
        const start = src.groups[g];
        const end = g + 1 < src.groups.length ? src.groups[g + 1] : tex.boxes[p].length;
        const offsets = [];
        let bit = 0;
        for (let f = start; f < end; f++) {
          const [, , bw, bh] = tex.boxes[p][f];
          offsets.push(bit);
          bit += Math.ceil((bw * bh) / 8) * 8;
        }
        const group = { start, bits: await inflate(bytes(data.masks)), offsets, pictures: data.pictures };
        src.loaded[g] = group;
        return group;
      });
    }
    return Promise.resolve(src.loaded[g]);
  }

  async function decodeJpeg(p, f, group, store) {
    const j = group.pictures[f - group.start];
    if (!j || !j.length) {
      store(f, null);
      return;
    }
    const b = await bitmap(bytes(j), 'image/jpeg');
    const [, , bw, bh] = tex.boxes[p][f];
    const t = texture(gl.RGBA8, 0, 0, gl.RGBA, gl.UNSIGNED_BYTE, b);
    b.close();
    store(f, { rgb: t, bytes: 4 * bw * bh });
  }

  // The frames of view p's H.264 group g (WebCodecs), each stored as it comes.
  async function decodeGroup(p, g, group, store) {
    const video = sources[p].video;
    const units = group.pictures;
    let out = 0;
    let failed = null;
    let chain = Promise.resolve();
    const decoder = new VideoDecoder({
      output: (frame) => {
        const i = group.start + out;
        out += 1;
        chain = chain.then(() => planes(frame)).then((t) => {
          t.bytes = t.size ? Math.round(t.size[0] * t.size[1] * 1.5) : 4 * video.width * video.height;
          store(i, t);
        }, (e) => { failed = e; });
      },
      error: (e) => { failed = e; },
    });
    decoder.configure({ codec: video.codec, codedWidth: video.width, codedHeight: video.height, optimizeForLatency: true });
    units.forEach((u, k) => {
      const i = group.start + k;
      decoder.decode(new EncodedVideoChunk({ type: k === 0 ? 'key' : 'delta', timestamp: i * 40000, data: bytes(u) }));
    });
    await decoder.flush();
    await chain;
    decoder.close();
    if (failed) throw failed;
    if (out !== units.length) {
      throw new Error(`view ${p}: ${out} of ${units.length} frames of group ${g} decoded`);
    }
  }

  // Frames the live page will want soon: the shown view's next frames and where a switch to a
  // neighbour would land.
  function upcoming(choice) {
    const V = S.views;
    const out = [];
    let f = choice.frame;
    for (let i = 0; i < 4; i++) {
      f = nextInLoop(choice.view, f);
      if (f < V[choice.view].frames) out.push([choice.view, f]);
    }
    const v = V[choice.view];
    if (choice.view + 1 < M && choice.frame < v.to_next.length) out.push([choice.view + 1, v.to_next[choice.frame]]);
    if (choice.view > 0 && choice.frame < v.to_prev.length) out.push([choice.view - 1, v.to_prev[choice.frame]]);
    return out.filter(([p, g]) => g !== null && g !== undefined && g < V[p].frames);
  }

  // ---- the live page ---------------------------------------------------------------------

  const qInput = document.getElementById('q');
  const speedInput = document.getElementById('speed');
  qInput.max = String(qMax);
  const live = {
    q: Math.min(qMax / 2, qMax),
    speed: 1,
    player: new Player(),
    renderer: new Renderer(),
    choice: null,
    acc: 0,
    last: null,
    dirty: true,
    drawn: 0,
    renderMs: 0,
    fpsCount: 0,
    fpsStart: null,
    fps: 0,
    waiting: false,
    redo: false,
    held: false,
    loadedMs: null,
    firstMs: null,
  };

  function setQ(v) {
    live.q = Math.min(qMax, Math.max(0, v));
    qInput.value = live.q.toFixed(2);
    document.getElementById('qval').textContent = live.q.toFixed(2);
    live.dirty = true;
  }
  setQ(S.start_q ?? Number((qMax / 2).toFixed(2)));
  qInput.addEventListener('input', () => setQ(parseFloat(qInput.value)));
  speedInput.addEventListener('input', () => {
    live.speed = parseFloat(speedInput.value);
    document.getElementById('speedval').textContent = live.speed.toFixed(2) + 'x';
  });
  document.addEventListener('keydown', (e) => {
    const step = e.shiftKey ? 0.25 : 0.05;
    if (e.key === 'ArrowRight' || e.key === 'ArrowUp') { setQ(live.q + step); e.preventDefault(); }
    if (e.key === 'ArrowLeft' || e.key === 'ArrowDown') { setQ(live.q - step); e.preventDefault(); }
  });
  // Dragging across the whole picture sweeps the whole range of viewpoints (mouse and touch).
  const stage = document.getElementById('stage');
  let drag = null;
  stage.addEventListener('pointerdown', (e) => {
    drag = { x: e.clientX, q: live.q };
    stage.setPointerCapture(e.pointerId);
    e.preventDefault();
  });
  stage.addEventListener('pointermove', (e) => {
    if (!drag) return;
    const width = stage.getBoundingClientRect().width || 1;
    setQ(drag.q + ((e.clientX - drag.x) / width) * qMax);
  });
  const endDrag = () => { drag = null; };
  stage.addEventListener('pointerup', endDrag);
  stage.addEventListener('pointercancel', endDrag);

  // Draws the live frame; false while its object frames are still decoding (the frame is drawn
  // once they are, and playback waits for it).
  function renderLive(advance) {
    const t0 = performance.now();
    if (advance || !live.choice) {
      live.blendBefore = live.renderer.blend;
      live.choice = live.player.advance(live.q);
    } else {
      // Paused, or redrawn after a wait: the same frame at the viewpoint, from the blend state
      // it was drawn with.
      live.renderer.blend = live.blendBefore;
    }
    const need = live.renderer.needs(live.q, live.choice);
    if (!frames.ready(need)) {
      live.waiting = true;
      frames.ensure(need).then(() => {
        live.waiting = false;
        live.redo = true;
        live.acc = 0;
      }, failed);
      return false;
    }
    frames.pin(need);
    const t = live.renderer.render(live.q, live.choice);
    present(t);
    sync();
    if (live.firstMs === null) live.firstMs = performance.now();
    live.renderMs = performance.now() - t0;
    live.drawn += 1;
    live.fpsCount += 1;
    frames.prefetch(upcoming(live.choice));
    return true;
  }

  function failed(e) {
    window.vt.error = String(e && e.message ? e.message : e);
    status.textContent = 'cannot play: ' + window.vt.error;
  }

  function tick(now) {
    requestAnimationFrame(tick);
    if (live.fpsStart === null) live.fpsStart = now;
    if (now - live.fpsStart >= 1000) {
      live.fps = (live.fpsCount * 1000) / (now - live.fpsStart);
      live.fpsCount = 0;
      live.fpsStart = now;
    }
    const dt = live.last === null ? 0 : Math.min((now - live.last) / 1000, 0.5);
    live.last = now;
    if (live.held || window.vt.error) return;
    if (live.waiting) {
      if (live.dirty) showStatus(true);
      return;
    }
    live.acc += dt * S.fps * live.speed;
    const due = live.acc >= 1 || !live.choice;
    let drawn;
    if (live.redo) {
      // The frame that waited for its object frames.
      live.redo = false;
      drawn = renderLive(false);
    } else if (due) {
      live.acc = Math.min(live.acc - 1, 1);
      drawn = renderLive(true);
    } else if (live.dirty) {
      drawn = renderLive(false);
    } else {
      return;
    }
    showStatus(!drawn);
    if (drawn) live.dirty = false;
  }

  // The status line; `waiting`: the shown frame's object pixels are still decoding.
  function showStatus(waiting) {
    const c = live.choice;
    const shown = c ? `view ${c.view} · frame ${c.frame} · ` : '';
    const wait = waiting ? ' · decoding' : '';
    status.textContent = `q ${live.q.toFixed(2)} · ${shown}loop wraps ${live.player.wraps} · switches ${live.player.switches} · ${live.fps.toFixed(1)} fps · render ${live.renderMs.toFixed(1)} ms · speed ${live.speed.toFixed(2)}x${wait}`;
  }

  // The page's hooks: tests drive and read the renderer through these.
  window.vt = {
    loaded: false,
    error: null,
    scene: S,
    // The live state.
    state: () => ({
      q: live.q,
      view: live.choice ? live.choice.view : null,
      frame: live.choice ? live.choice.frame : null,
      drawn: live.drawn,
      wraps: live.player.wraps,
      switches: live.player.switches,
      fps: live.fps,
      renderMs: live.renderMs,
      // Milliseconds from opening the page to its assets loaded and to its first frame drawn.
      loadedMs: live.loadedMs,
      firstMs: live.firstMs,
      // Bytes of object frames held on the GPU now and at most, the budget, frames decoded.
      gpuBytes: frames.used,
      gpuPeak: frames.peak,
      gpuBudget: S.gpu_bytes,
      decoded: frames.decoded,
    }),
    // Plays the viewpoint path `qs` from the start with a new player and renderer (as
    // vt_io::scene::LoadedScene::play does) and returns the frames at the indices in `keep`:
    // { i, view, frame, step, rgb (base64, top row first) }.
    // (The live page holds still meanwhile.)
    play: async (qs, keep) => {
      const player = new Player();
      const renderer = new Renderer();
      const want = new Set(keep);
      const out = [];
      live.held = true;
      try {
        for (let i = 0; i < qs.length; i++) {
          const q = qs[i];
          const c = player.advance(q);
          await frames.ensure(renderer.needs(q, c));
          const t = renderer.render(q, c);
          if (want.has(i)) out.push({ i, view: c.view, frame: c.frame, step: c.step, rgb: readRgb(t) });
        }
      } finally {
        live.held = false;
        live.dirty = true;
      }
      return out;
    },
    // Renders n frames back to back (the viewpoint moving, the video playing), each finished
    // on the GPU (read back); returns frames per second.
    // Frames decoded on the way count in the time, as they would live.
    bench: async (n) => {
      const player = new Player();
      const renderer = new Renderer();
      live.held = true;
      const t0 = performance.now();
      try {
        for (let i = 0; i < n; i++) {
          const q = (qMax * (0.5 + 0.5 * Math.sin(i / 7))) || 0;
          const c = player.advance(q);
          await frames.ensure(renderer.needs(q, c));
          const t = renderer.render(q, c);
          present(t);
          sync();
        }
      } finally {
        live.held = false;
        live.dirty = true;
      }
      return (n * 1000) / (performance.now() - t0);
    },
  };

  load().then(() => {
    window.vt.loaded = true;
    live.loadedMs = performance.now();
    requestAnimationFrame(tick);
  }).catch(failed);
})();
