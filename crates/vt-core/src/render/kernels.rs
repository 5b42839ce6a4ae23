//! The renderer's per-pixel passes: eq. (3)'s blended warp, the parallax morph and the
//! object composite, rows in parallel through `simd::dispatch`.

use image::RgbImage;
use rayon::prelude::*;

use super::ObjectPatch;
use crate::round_u8;
use crate::warp::{
    nearest_cell, sample_value, state, Interpolation, Mapping, Padded, Run, Sampler, BILINEAR,
    BILINEAR_FIXED, CHUNK, NEAREST, ROWS_PER_JOB,
};
use crate::{Homography, Point};

use crate::parallax::{morph_weights, CONVERGED_PX, FIXED_POINT_STEPS as MORPH_STEPS};

/// The background beyond the plane (the morph of [`crate::parallax`]) at fraction `frac` of
/// the pair: each output pixel `z` is traced into both views (`x0 = H_(p,q)^-1 z`, then the
/// fixed point `x = x0 - frac u(x)` along that view's parallax field; `1 - frac` from the
/// other), sampled bilinearly, divided by the view's gain (against q's exposure) and blended
/// with weights `(1 - frac, frac)` (one view alone where the other's sample falls outside its
/// image; both from their replicated edges where neither sees; the nearer surface alone where
/// both traces converged on different ones; the view whose trace converged preferred where only
/// one did: [`crate::parallax::morph_weights`], as in [`crate::parallax::morph`]). Rows in
/// parallel; written to `out` and `copy` when given.
pub(super) fn morph_blend(
    images: [&Padded; 2],
    par: &crate::parallax::PairParallax,
    h: [&Homography; 2],
    gain_inv: [[f32; 3]; 2],
    frac: f64,
    out: &mut RgbImage,
    copy: Option<&mut [u8]>,
) {
    let w = out.width() as usize;
    let size = out.dimensions();
    let towards = crate::parallax::nearer_towards(par, h[0], h[1], size);
    let side = |s: usize| {
        let fld = [&par.a, &par.b][s];
        MorphSide {
            sampler: Sampler::padded(
                images[s],
                h[s],
                Interpolation::Bilinear,
                Mapping::Division,
                size,
            ),
            iw: fld.width() as usize,
            ih: fld.height() as usize,
            flow: fld.flow(),
            frac: if s == 0 { frac } else { 1.0 - frac },
            gain_inv: gain_inv[s],
            toward: towards[s],
        }
    };
    let sides = [side(0), side(1)];
    let job = |y: usize, row: &mut [u8], copy: Option<&mut [u8]>| {
        crate::simd::dispatch(MorphRow {
            sides: &sides,
            frac: frac as f32,
            y,
            row,
            copy,
            w,
        })
    };
    match copy {
        Some(copy) => out
            .as_mut()
            .par_chunks_mut(3 * w)
            .zip(copy.par_chunks_mut(3 * w))
            .enumerate()
            .for_each(|(y, (row, c))| job(y, row, Some(c))),
        None => out
            .as_mut()
            .par_chunks_mut(3 * w)
            .enumerate()
            .for_each(|(y, row)| job(y, row, None)),
    }
}

/// One view's constants for the morph's pixel loop.
struct MorphSide<'a> {
    /// The view's background through `H_(p,q)` (exact bilinear, replicated edges).
    sampler: Sampler<'a>,
    iw: usize,
    ih: usize,
    flow: &'a [[i16; 2]],
    frac: f64,
    gain_inv: [f32; 3],
    /// A flow's dot product with it grows as the surface comes nearer
    /// ([`crate::parallax::nearer_towards`]).
    toward: [f32; 2],
}

/// One output row of the morph ([`morph_blend`]), as a [`crate::simd::Kernel`]: runs of
/// [`CHUNK`] pixels, each step of the fixed point done for the whole run before the next (the
/// run's independent chains of load, multiply, load overlap in the CPU), sampled by the plane
/// warp's sampler at the traced points.
struct MorphRow<'a, 'b> {
    sides: &'a [MorphSide<'b>; 2],
    frac: f32,
    y: usize,
    row: &'a mut [u8],
    copy: Option<&'a mut [u8]>,
    w: usize,
}

impl crate::simd::Kernel for MorphRow<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let MorphRow {
            sides,
            frac,
            y,
            row,
            copy,
            w,
        } = self;
        // On the stack, once per row: rayon's per-job init would allocate.
        let mut runs = [Run::default(), Run::default()];
        let mut converged = [[false; CHUNK]; 2];
        let mut nearness = [[0f32; CHUNK]; 2];
        let c2 = (CONVERGED_PX * CONVERGED_PX) as f32;
        let mut x_start = 0;
        while x_start < w {
            let n = CHUNK.min(w - x_start);
            for (s, (sd, run)) in sides.iter().zip(runs.iter_mut()).enumerate() {
                sd.sampler.map_into(y, x_start, run);
                // The trace in f32 (16 lanes with AVX-512): a pixel's position to 1/4096 px
                // below 4096 px.
                let (bx, by) = (run.sx.map(|v| v as f32), run.sy.map(|v| v as f32));
                let (mut sx, mut sy) = (bx, by);
                let (iw, ih) = (sd.iw, sd.ih);
                let fr = sd.frac as f32 * crate::parallax::FLOW_UNIT;
                let flow = sd.flow;
                let last = flow.len() - 1;
                let (mut px, mut py) = (sx, sy);
                for _ in 0..MORPH_STEPS {
                    (px, py) = (sx, sy);
                    for i in 0..CHUNK {
                        // `min(last)`: the index is provably in the slice, so the loop has no
                        // bounds-check branch and vectorises with gathers.
                        let u = flow[nearest_cell(sx[i], sy[i], iw, ih).min(last)];
                        sx[i] = bx[i] - f32::from(u[0]) * fr;
                        sy[i] = by[i] - f32::from(u[1]) * fr;
                    }
                }
                // Converged: the last step moved it less than CONVERGED_PX (see
                // `parallax::morph`).
                for i in 0..CHUNK {
                    let (ex, ey) = (sx[i] - px[i], sy[i] - py[i]);
                    converged[s][i] = ex * ex + ey * ey < c2;
                    let u = flow[nearest_cell(sx[i], sy[i], iw, ih).min(last)];
                    nearness[s][i] = (f32::from(u[0]) * sd.toward[0]
                        + f32::from(u[1]) * sd.toward[1])
                        * crate::parallax::FLOW_UNIT;
                }
                run.sx = sx.map(f64::from);
                run.sy = sy.map(f64::from);
                sd.sampler.taps_at(n, run);
            }
            let [ra, rb] = &runs;
            let (ga, gb) = (sides[0].gain_inv, sides[1].gain_inv);
            for i in 0..n {
                let (wa, wb) = morph_weights(
                    frac,
                    [ra.state[i] == state::INSIDE, rb.state[i] == state::INSIDE],
                    [converged[0][i], converged[1][i]],
                    [nearness[0][i], nearness[1][i]],
                );
                let norm = 1.0 / (wa + wb);
                let x = x_start + i;
                for k in 0..3 {
                    let va = sample_value::<BILINEAR>(ra, i, k) * ga[k];
                    let vb = sample_value::<BILINEAR>(rb, i, k) * gb[k];
                    row[3 * x + k] = round_u8((va * wa + vb * wb) * norm);
                }
            }
            x_start += n;
        }
        if let Some(copy) = copy {
            copy.copy_from_slice(row);
        }
    }
}

/// One background of eq. (3): the image, its `H_(p,q)`, its inverse gain and blend weight.
pub(super) struct Source<'a> {
    pub(super) image: &'a Padded,
    pub(super) h: &'a Homography,
    pub(super) gain_inv: [f32; 3],
    pub(super) weight: f32,
}

/// Eq. (3) in one pass: each output pixel samples every source through its homography
/// (edges replicated), and blends with the sources' weights renormalised over the sources whose
/// sample really falls inside their image (`-0.5 <= x < w - 0.5`), so a strip only one view sees
/// takes that view alone instead of fading to black. Where no source sees the pixel, all are
/// blended from their replicated edges.
///
/// Sampling is [`crate::warp`]'s sampler (runs of [`CHUNK`] pixels, the renderer's
/// division mapping, replicated border, read from the padded backgrounds); rows in parallel.
/// Each run is written to `out` and, when given, to `copy` (the same size): the frame starts
/// from the background without a second pass over it.
pub(super) fn blend_warps<'a>(
    sources: &[Source<'a>],
    interp: Interpolation,
    out: &mut RgbImage,
    copy: Option<&mut [u8]>,
) {
    let w = out.width() as usize;
    if w == 0 || sources.is_empty() {
        return;
    }
    let size = out.dimensions();
    let sampler = |s: &Source<'a>| {
        let sampler = Sampler::padded(s.image, s.h, interp, Mapping::Division, size);
        // weight * gain_inv[k], in the order the per-pixel formula multiplies them.
        let wg = s.gain_inv.map(|g| s.weight * g);
        (sampler, wg, s.weight)
    };
    let first = sampler(&sources[0]);
    // One source: the second contributes nothing (its state stays NONE).
    let second = sources.get(1).map(sampler);
    let band = w * 3 * ROWS_PER_JOB;
    let job = |(i, (rows, copy)): (usize, (&mut [u8], Option<&mut [u8]>))| {
        crate::simd::dispatch(BlendBand {
            first: &first,
            second: second.as_ref(),
            y0: i * ROWS_PER_JOB,
            rows,
            copy,
            w,
        })
    };
    match copy {
        Some(copy) => out
            .as_mut()
            .par_chunks_mut(band)
            .zip(copy.par_chunks_mut(band).map(Some))
            .enumerate()
            .for_each(job),
        None => out
            .as_mut()
            .par_chunks_mut(band)
            .map(|rows| (rows, None))
            .enumerate()
            .for_each(job),
    }
}

/// A sampler with its weights times inverse gains, and its weight.
type Weighted<'a> = (Sampler<'a>, [f32; 3], f32);

/// Rows of [`blend_warps`] as a [`crate::simd::Kernel`].
struct BlendBand<'a, 'b> {
    first: &'a Weighted<'b>,
    second: Option<&'a Weighted<'b>>,
    y0: usize,
    rows: &'a mut [u8],
    copy: Option<&'a mut [u8]>,
    w: usize,
}

impl crate::simd::Kernel for BlendBand<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        match self.first.0.interpolation() {
            Interpolation::Nearest => self.blend::<NEAREST>(),
            Interpolation::Bilinear => self.blend::<BILINEAR>(),
            Interpolation::BilinearFixed => self.blend::<BILINEAR_FIXED>(),
        }
    }
}

impl BlendBand<'_, '_> {
    /// The band's rows, sampled and blended in one pass per run of pixels.
    #[inline(always)]
    fn blend<const MODE: u8>(self) {
        let BlendBand {
            first,
            second,
            y0,
            rows,
            mut copy,
            w,
        } = self;
        // On the stack, once per band: rayon's per-job init would allocate.
        let (r0, r1) = (&mut Run::default(), &mut Run::default());
        let (wg0, weight0) = (first.1, first.2);
        let (wg1, weight1) = second.map_or(([0.0; 3], 0.0), |s| (s.1, s.2));
        let (mut sel0, mut sel1, mut ws) = ([false; CHUNK], [false; CHUNK], [0f32; CHUNK]);
        let mut bytes = [[0u8; CHUNK]; 3];
        let mut buf = [0u8; CHUNK * 3];
        for (r, row) in rows.chunks_mut(w * 3).enumerate() {
            let y = y0 + r;
            for (c, px) in row.chunks_mut(CHUNK * 3).enumerate() {
                let n = px.len() / 3;
                // A source without a sample (empty image, or no second source) has states NONE
                // and is never selected below, whatever its taps hold.
                first.0.taps(y, c * CHUNK, n, r0);
                match second {
                    Some(s) => {
                        s.0.taps(y, c * CHUNK, n, r1);
                    }
                    None => r1.state = [state::NONE; CHUNK],
                }
                // Per pixel: the sum runs over the sources whose sample is inside if any
                // weight is there, else over all with a sample; divided by their weights' sum.
                for i in 0..CHUNK {
                    let pick = |c: bool, v: f32| if c { v } else { 0.0 };
                    let (s0, s1) = (r0.state[i], r1.state[i]);
                    let (in0, in1) = (s0 == state::INSIDE, s1 == state::INSIDE);
                    let (has0, has1) = (s0 != state::NONE, s1 != state::NONE);
                    let ws_in = (0.0 + pick(in0, weight0)) + pick(in1, weight1);
                    let ws_all = (0.0 + pick(has0, weight0)) + pick(has1, weight1);
                    let use_in = ws_in > 0.0;
                    sel0[i] = if use_in { in0 } else { has0 };
                    sel1[i] = if use_in { in1 } else { has1 };
                    ws[i] = if use_in { ws_in } else { ws_all };
                }
                for (k, bytes) in bytes.iter_mut().enumerate() {
                    for i in 0..CHUNK {
                        // v = weight * gain_inv * sample, summed over the selected sources in
                        // order. Selects instead of branches (so it vectorises); `0 + v` and
                        // `v + 0` are `v`, so the sum equals the branchy one bit for bit.
                        let pick = |c: bool, v: f32| if c { v } else { 0.0 };
                        let v0 = wg0[k] * sample_value::<MODE>(r0, i, k);
                        let v1 = wg1[k] * sample_value::<MODE>(r1, i, k);
                        let acc = (0.0 + pick(sel0[i], v0)) + pick(sel1[i], v1);
                        let v = round_u8(acc / ws[i]);
                        bytes[i] = if ws[i] > 0.0 { v } else { 0 };
                    }
                }
                // Interleaved into RGB (a strided store the compiler shuffles), then copied.
                for i in 0..CHUNK {
                    for k in 0..3 {
                        buf[3 * i + k] = bytes[k][i];
                    }
                }
                px.copy_from_slice(&buf[..px.len()]);
                if let Some(copy) = copy.as_deref_mut() {
                    let at = r * w * 3 + c * CHUNK * 3;
                    copy[at..at + px.len()].copy_from_slice(&buf[..px.len()]);
                }
            }
        }
    }
}

/// Warps the object patch by `h` (inverse mapping over the forward image of the box) and writes
/// it over `out` with opacity `alpha`. Colours are sampled bilinearly from object pixels only
/// (mask-weighted); a pixel belongs to the object where the bilinear mask coverage is >= 0.5
/// (nearest: where the nearest source pixel is object). Where the view's dynamic-region alpha
/// (sampled at the nearest source pixel) is set, it scales the opacity: the region's feathered
/// edge blends the source frame into the background instead of cutting it. Only rows whose
/// index is a multiple of `rows` are written (1: all; see [`super::Renderer::sample_rows`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn composite(
    patch: &ObjectPatch,
    h: &Homography,
    interp: Interpolation,
    gain: [f32; 3],
    alpha: f32,
    dynamic: Option<&image::GrayImage>,
    rows: usize,
    out: &mut RgbImage,
) {
    if patch.width == 0 || patch.height == 0 {
        return;
    }
    let (ow, oh) = out.dimensions();
    let (pw, ph) = (patch.width as i64, patch.height as i64);
    let (x0, y0) = (patch.x0 as f64, patch.y0 as f64);
    // Output region: forward image of the box corners (w > 0 at all corners, else everything).
    let m = h.raw().0;
    let corners = [
        (x0 - 1.0, y0 - 1.0),
        (x0 + pw as f64, y0 - 1.0),
        (x0 - 1.0, y0 + ph as f64),
        (x0 + pw as f64, y0 + ph as f64),
    ];
    let mut region = (0u32, 0u32, ow, oh);
    if corners
        .iter()
        .all(|&(x, y)| m[(2, 0)] * x + m[(2, 1)] * y + m[(2, 2)] > 0.0)
    {
        let (mut lx, mut ly, mut hx, mut hy) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for &(x, y) in &corners {
            if let Some(p) = h.apply(Point::new(x, y)) {
                lx = lx.min(p.x);
                ly = ly.min(p.y);
                hx = hx.max(p.x);
                hy = hy.max(p.y);
            }
        }
        let cl = |v: f64, hi: u32| v.clamp(0.0, hi as f64) as u32;
        region = (
            cl(lx.floor() - 1.0, ow),
            cl(ly.floor() - 1.0, oh),
            cl(hx.ceil() + 2.0, ow),
            cl(hy.ceil() + 2.0, oh),
        );
    }
    let inv = h.raw().1;
    let row_len = ow as usize * 3;
    // The dynamic region's alpha is read at the source pixel: the fast path needs the box
    // inside it (always, in a scene: both are the view's size).
    let inside = dynamic.is_none_or(|d| {
        patch.x0 + patch.width <= d.width() && patch.y0 + patch.height <= d.height()
    });
    if let (Some(shift), true) = (integer_shift(inv), inside) {
        composite_shifted(patch, shift, gain, alpha, dynamic, region, rows, out);
        return;
    }
    let every = rows.max(1);
    let rows = &mut out.as_mut()[region.1 as usize * row_len..region.3 as usize * row_len];
    let ctx = CompositeCtx {
        patch,
        inv,
        interp,
        gain,
        alpha,
        dynamic,
        x0,
        y0,
        pw,
        ph,
        region,
    };
    // Rows in parallel (each pixel is its own computation, so the same bytes), each through
    // the SIMD dispatch (floor and rounding inline instead of library calls).
    rows.par_chunks_mut(row_len)
        .enumerate()
        .filter(|(r, _)| (region.1 as usize + r).is_multiple_of(every))
        .for_each(|(r, raw)| {
            crate::simd::dispatch(CompositeRow {
                ctx: &ctx,
                y: region.1 + r as u32,
                raw,
            })
        });
}

/// `(tx, ty)` when `inv` maps output pixel `(x, y)` to source `(x + tx, y + ty)` exactly: the
/// identity (a single view, or q at a view whose fit is exact) or a shift by whole pixels.
fn integer_shift(inv: &nalgebra::Matrix3<f64>) -> Option<(i64, i64)> {
    let (tx, ty) = (inv[(0, 2)], inv[(1, 2)]);
    let whole = |t: f64| t.fract() == 0.0 && t.abs() <= 1e9;
    (inv[(0, 0)] == 1.0
        && inv[(0, 1)] == 0.0
        && inv[(1, 0)] == 0.0
        && inv[(1, 1)] == 1.0
        && inv[(2, 0)] == 0.0
        && inv[(2, 1)] == 0.0
        && inv[(2, 2)] == 1.0
        && whole(tx)
        && whole(ty))
    .then_some((tx as i64, ty as i64))
}

/// [`composite`] when the mapping is a shift by whole pixels: every output pixel's source is
/// one patch pixel, its bilinear taps have weights `(1, 0, 0, 0)` (nearest picks the same
/// pixel), so the general path's colour is that pixel's own and its coverage its mask bit.
/// The same arithmetic on the same values, in the same order, as [`CompositeRow`]: the same
/// bytes, without the per-pixel projection and tap tests; only the box's pixels are visited.
#[allow(clippy::too_many_arguments)]
fn composite_shifted(
    patch: &ObjectPatch,
    (tx, ty): (i64, i64),
    gain: [f32; 3],
    alpha: f32,
    dynamic: Option<&image::GrayImage>,
    region: (u32, u32, u32, u32),
    rows: usize,
    out: &mut RgbImage,
) {
    let (px0, py0) = (patch.x0 as i64, patch.y0 as i64);
    let (pw, ph) = (patch.width as i64, patch.height as i64);
    // Output columns and rows whose source lies in the box, within the region.
    let xa = (px0 - tx).max(region.0 as i64);
    let xb = (px0 + pw - tx).min(region.2 as i64);
    let ya = (py0 - ty).max(region.1 as i64);
    let yb = (py0 + ph - ty).min(region.3 as i64);
    if xa >= xb || ya >= yb {
        return;
    }
    let (xa, xb, ya, yb) = (xa as usize, xb as usize, ya as usize, yb as usize);
    let row_len = out.width() as usize * 3;
    let every = rows.max(1);
    let rows = &mut out.as_mut()[ya * row_len..yb * row_len];
    rows.par_chunks_mut(row_len)
        .enumerate()
        .filter(|(r, _)| (ya + r).is_multiple_of(every))
        .for_each(|(r, raw)| {
            let y = (ya + r) as i64;
            let (sy, lx0) = (y + ty, xa as i64 + tx - px0);
            let at = ((sy - py0) * pw + lx0) as usize;
            let n = xb - xa;
            // The dynamic region's alpha at the source pixel (the box is inside it: the
            // general path's clamp changes nothing).
            let dyn_row = dynamic.map(|d| {
                let start = (sy * d.width() as i64 + xa as i64 + tx) as usize;
                &d.as_raw()[start..start + n]
            });
            crate::simd::dispatch(ShiftedRow {
                mask: &patch.mask[at..at + n],
                rgb: &patch.rgb[3 * at..3 * (at + n)],
                dynamic: dyn_row,
                gain,
                alpha,
                out: &mut raw[3 * xa..3 * xb],
            })
        });
}

/// One output row of [`composite_shifted`] as a [`crate::simd::Kernel`].
struct ShiftedRow<'a> {
    mask: &'a [u8],
    rgb: &'a [u8],
    dynamic: Option<&'a [u8]>,
    gain: [f32; 3],
    alpha: f32,
    out: &'a mut [u8],
}

impl crate::simd::Kernel for ShiftedRow<'_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let ShiftedRow {
            mask,
            rgb,
            dynamic,
            gain,
            alpha,
            out,
        } = self;
        // Runs of CHUNK pixels through fixed-size buffers (so the loops vectorise), a pixel's
        // three channels de-interleaved by strided access, the mask a select.
        let mut al = [0f32; CHUNK];
        let unit = gain == [1.0; 3];
        let (mut src, mut dst) = ([0u8; 3 * CHUNK], [0u8; 3 * CHUNK]);
        for start in (0..mask.len()).step_by(CHUNK) {
            let n = CHUNK.min(mask.len() - start);
            let m = &mask[start..start + n];
            if m.iter().all(|&m| m == 0) {
                continue;
            }
            let mut set = [false; CHUNK];
            for (s, &m) in set.iter_mut().zip(m) {
                *s = m != 0;
            }
            match dynamic {
                Some(d) => {
                    for (al, &a) in al.iter_mut().zip(&d[start..start + n]) {
                        *al = if a > 0 {
                            alpha * a as f32 / 255.0
                        } else {
                            alpha
                        };
                    }
                }
                None => al = [alpha; CHUNK],
            }
            let (s3, o3) = (
                &rgb[3 * start..3 * (start + n)],
                &mut out[3 * start..3 * (start + n)],
            );
            // Opaque pixels of unit gain (a single view's, inside its dynamic region):
            // `1 * v + 0 * old` rounds to `v` itself, so the run is a copy.
            if unit && set[..n].iter().all(|&s| s) && al[..n].iter().all(|&a| a == 1.0) {
                o3.copy_from_slice(s3);
                continue;
            }
            src[..3 * n].copy_from_slice(s3);
            dst[..3 * n].copy_from_slice(o3);
            for c in 0..3 {
                for i in 0..CHUNK {
                    let v = src[3 * i + c] as f32 / gain[c];
                    let old = dst[3 * i + c];
                    let blended = al[i] * v + (1.0 - al[i]) * old as f32;
                    dst[3 * i + c] = if set[i] { round_u8(blended) } else { old };
                }
            }
            o3.copy_from_slice(&dst[..3 * n]);
        }
    }
}

/// What every row of [`composite`] reads.
#[derive(Clone, Copy)]
struct CompositeCtx<'a> {
    patch: &'a ObjectPatch,
    inv: &'a nalgebra::Matrix3<f64>,
    interp: Interpolation,
    gain: [f32; 3],
    alpha: f32,
    dynamic: Option<&'a image::GrayImage>,
    x0: f64,
    y0: f64,
    pw: i64,
    ph: i64,
    region: (u32, u32, u32, u32),
}

impl CompositeCtx<'_> {
    /// The patch index of object pixel `(x, y)` (view coordinates), if it is one.
    #[inline(always)]
    fn sample(&self, x: i64, y: i64) -> Option<usize> {
        let (lx, ly) = (x - self.patch.x0 as i64, y - self.patch.y0 as i64);
        if lx < 0 || ly < 0 || lx >= self.pw || ly >= self.ph {
            return None;
        }
        let i = (ly * self.pw + lx) as usize;
        (self.patch.mask[i] != 0).then_some(i)
    }
}

/// One output row of [`composite`] as a [`crate::simd::Kernel`].
struct CompositeRow<'a, 'b> {
    ctx: &'a CompositeCtx<'b>,
    y: u32,
    raw: &'a mut [u8],
}

impl crate::simd::Kernel for CompositeRow<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let CompositeRow { ctx, y, raw } = self;
        let CompositeCtx {
            inv,
            x0,
            y0,
            pw,
            ph,
            region,
            ..
        } = *ctx;
        let yf = y as f64;
        // Runs of CHUNK pixels: first every pixel's source point (a loop the compiler
        // vectorises, divisions included), then the taps of those that land by the box. A zero
        // `w` divides to an infinity or NaN, which the finiteness test drops, as the per-pixel
        // test did.
        let (mut sxs, mut sys, mut lands) = ([0f64; CHUNK], [0f64; CHUNK], [false; CHUNK]);
        let (lo_x, lo_y, hi_x, hi_y) = (x0 - 1.0, y0 - 1.0, x0 + pw as f64, y0 + ph as f64);
        for start in (region.0..region.2).step_by(CHUNK) {
            for i in 0..CHUNK {
                let xf = (start as usize + i) as f64;
                let w = inv[(2, 0)] * xf + inv[(2, 1)] * yf + inv[(2, 2)];
                let sx = (inv[(0, 0)] * xf + inv[(0, 1)] * yf + inv[(0, 2)]) / w;
                let sy = (inv[(1, 0)] * xf + inv[(1, 1)] * yf + inv[(1, 2)]) / w;
                sxs[i] = sx;
                sys[i] = sy;
                lands[i] = sx.is_finite()
                    && sy.is_finite()
                    && sx >= lo_x
                    && sy >= lo_y
                    && sx <= hi_x
                    && sy <= hi_y;
            }
            let n = CHUNK.min((region.2 - start) as usize);
            for i in 0..n {
                if !lands[i] {
                    continue;
                }
                let (x, sx, sy) = (start + i as u32, sxs[i], sys[i]);
                composite_pixel(ctx, x, sx, sy, raw);
            }
        }
    }
}

/// One pixel of [`CompositeRow`]: output column `x` of the row `raw`, whose source point
/// `(sx, sy)` lies by the box.
#[inline(always)]
fn composite_pixel(ctx: &CompositeCtx, x: u32, sx: f64, sy: f64, raw: &mut [u8]) {
    let CompositeCtx {
        patch,
        interp,
        gain,
        alpha,
        dynamic,
        ..
    } = *ctx;
    let sample = |x: i64, y: i64| ctx.sample(x, y);
    let mut colour = [0f32; 3];
    match interp {
        Interpolation::Nearest => {
            let Some(i) = sample(sx.round_ties_even() as i64, sy.round_ties_even() as i64) else {
                return;
            };
            for c in 0..3 {
                colour[c] = patch.rgb[i * 3 + c] as f32;
            }
        }
        Interpolation::Bilinear | Interpolation::BilinearFixed => {
            let (fx0, fy0) = (sx.floor(), sy.floor());
            let (fx, fy) = ((sx - fx0) as f32, (sy - fy0) as f32);
            let (ix, iy) = (fx0 as i64, fy0 as i64);
            let taps = [
                (ix, iy, (1.0 - fx) * (1.0 - fy)),
                (ix + 1, iy, fx * (1.0 - fy)),
                (ix, iy + 1, (1.0 - fx) * fy),
                (ix + 1, iy + 1, fx * fy),
            ];
            let mut cover = 0f32;
            for &(tx, ty, wt) in &taps {
                if let Some(i) = sample(tx, ty) {
                    cover += wt;
                    for c in 0..3 {
                        colour[c] += wt * patch.rgb[i * 3 + c] as f32;
                    }
                }
            }
            if cover < 0.5 {
                return;
            }
            for v in &mut colour {
                *v /= cover;
            }
        }
    }
    let o = x as usize * 3;
    let alpha = match dynamic {
        Some(d) => {
            let (dw, dh) = (d.width() as i64, d.height() as i64);
            let (ax, ay) = (
                (sx.round_ties_even() as i64).clamp(0, dw - 1),
                (sy.round_ties_even() as i64).clamp(0, dh - 1),
            );
            let a = d.as_raw()[(ay * dw + ax) as usize];
            if a > 0 {
                alpha * a as f32 / 255.0
            } else {
                alpha
            }
        }
        None => alpha,
    };
    for c in 0..3 {
        let v = colour[c] / gain[c];
        let blended = alpha * v + (1.0 - alpha) * raw[o + c] as f32;
        raw[o + c] = round_u8(blended);
    }
}
