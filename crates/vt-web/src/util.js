// What vt's two pages share (written ahead of each page's script): base64 payloads as bytes,
// scripts loaded on demand, and a framebuffer read back as base64 RGB rows.
const vtUtil = {
  bytes(b64) {
    const bin = atob(b64);
    const out = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
    return out;
  },

  // zlib-deflated bytes inflated.
  async inflate(data) {
    const stream = new Blob([data]).stream().pipeThrough(new DecompressionStream('deflate'));
    return new Uint8Array(await new Response(stream).arrayBuffer());
  },

  // Bits packed least significant first, `count` of them from byte `offset`, as 0/255 bytes.
  unpackBits(bits, offset, count) {
    const out = new Uint8Array(count);
    for (let i = 0; i < count; i++) out[i] = (bits[offset + (i >> 3)] >> (i & 7)) & 1 ? 255 : 0;
    return out;
  },

  loadScript(src) {
    return new Promise((resolve, reject) => {
      const el = document.createElement('script');
      el.src = src;
      el.onload = resolve;
      el.onerror = () => reject(new Error('cannot load ' + src));
      document.head.appendChild(el);
    });
  },

  // The w x h pixels of framebuffer `fb` as RGB bytes, base64, in the framebuffer's row order.
  readRgb(gl, fb, w, h) {
    gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
    const rgba = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, rgba);
    const rgb = new Uint8Array(w * h * 3);
    for (let i = 0, j = 0; i < rgba.length; i += 4, j += 3) {
      rgb[j] = rgba[i];
      rgb[j + 1] = rgba[i + 1];
      rgb[j + 2] = rgba[i + 2];
    }
    let s = '';
    for (let i = 0; i < rgb.length; i += 0x8000) s += String.fromCharCode.apply(null, rgb.subarray(i, i + 0x8000));
    return btoa(s);
  },
};
