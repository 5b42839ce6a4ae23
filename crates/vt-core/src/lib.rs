//! vt-core: every algorithm of vt in pure Rust, with no I/O and no OpenCV.
//!
//! System A (viewpoint-varying video textures, seed thesis Sec. 3) offline analysis:
//! [`median`] backgrounds, [`blur`], [`mask`] extraction by background subtraction,
//! [`loops`] (eq. 1), [`homography`] and [`model`] selection between views, [`warp`] of masks,
//! [`transition`] tables (eq. 2), and the [`analysis`] pipeline that ties them together;
//! online, [`render`] (eq. 3-6): the source-frame player and the intermediate-view renderer.
//!
//! Images are the `image` crate's [`image::RgbImage`]; pixel centres sit at integer
//! coordinates `(x, y) = (column, row)`, origin top-left, as in OpenCV. Video frames may also
//! arrive as planar 4:2:0 ([`yuv`]), the decoders' own form, which the analysis keeps between
//! its passes and converts to RGB where it needs pixels.
#![deny(missing_docs)]

pub mod align;
pub mod analysis;
pub mod appearance;
pub mod blur;
mod error;
pub mod homography;
pub mod loops;
pub mod mask;
pub mod median;
pub mod metrics;
pub mod model;
pub mod noise;
pub mod packed;
pub mod parallax;
pub mod regions;
pub mod register;
pub mod render;
pub mod rng;
pub mod seam;
mod simd;
pub mod stabilize;
pub mod transition;
pub mod warp;
pub mod yuv;

pub use error::{Error, ExternalError, Result};
pub use homography::{Homography, Point};
pub use mask::Mask;

/// Rounds a non-negative value to the nearest `u8` (halves up), saturating at 255; negative
/// values and NaN give 0.
///
/// Same results as `v.round().clamp(0.0, 255.0) as u8` for every value that occurs here (convex
/// combinations of bytes), but `f32::round` is a library call on baseline x86-64 (no SSE4.1),
/// which kept the blur and warp loops from vectorising (3x3 blur of 640x360: 1.38 -> 0.77 ms).
#[inline(always)]
pub(crate) fn round_u8(v: f32) -> u8 {
    // The saturating `(v + 0.5) as u8`, written so it vectorises (a saturating float-to-int
    // conversion does not): clamp to [0, 255.5] (NaN to 0), floor by the 2^23 rounding trick,
    // and read the integer from the mantissa bits. Same value for every f32 (tested).
    const MAGIC: f32 = 8_388_608.0;
    let x = v + 0.5;
    let x = if x >= 0.0 { x } else { 0.0 };
    let x = if x <= 255.5 { x } else { 255.5 };
    let r = (x + MAGIC) - MAGIC;
    let floor = if r > x { r - 1.0 } else { r };
    ((floor + MAGIC).to_bits() & 0xff) as u8
}

/// [`round_u8`] for a value known to lie in `[0, 255.5)` (a convex combination of bytes, up
/// to `f32` rounding), as a `u32`: the same `floor(v + 0.5)` without the clamps, which change
/// nothing there.
#[inline(always)]
pub(crate) fn round_u8_in_range(v: f32) -> u32 {
    debug_assert!((0.0..255.5).contains(&v), "{v}");
    const MAGIC: f32 = 8_388_608.0;
    let x = v + 0.5;
    let r = (x + MAGIC) - MAGIC;
    let floor = if r > x { r - 1.0 } else { r };
    (floor + MAGIC).to_bits() & 0xff
}
