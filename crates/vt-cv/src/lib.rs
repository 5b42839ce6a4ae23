//! vt-cv: the OpenCV twin of vt-core, with the same shapes so a caller can swap one for the
//! other call for call, and `cross-check` (run by `cargo xtask cross-check`) can assert that
//! they agree. It exists to check vt-core; nothing in vt depends on it at run time.
//!
//! Every function takes and returns vt-core's types (`image::RgbImage`, [`vt_core::Mask`],
//! [`vt_core::Homography`], [`vt_core::Point`], the parameter structs) and converts to and from
//! OpenCV `Mat`s at the boundary ([`convert`]). Where vt-core's rules are not OpenCV's
//! (frame-count and size checks) vt-cv applies vt-core's, returning
//! vt-core's errors wrapped in [`Error::Core`].
//!
//! | vt-cv | OpenCV | mirrors |
//! | --- | --- | --- |
//! | [`median::temporal_median`] | `sort(SORT_EVERY_COLUMN)` | `vt_core::median::temporal_median` |
//! | [`blur::gaussian_blur`] | `GaussianBlur` | `vt_core::blur::gaussian_blur` |
//! | [`mask::threshold_mask`], [`mask::foreground_mask`] | `absdiff`, `split`, `max`, `threshold`, `erode`, `dilate` | `vt_core::analysis::{threshold_mask, foreground_mask}` |
//! | [`mask::morph`] | `erode`, `dilate` (`MORPH_RECT`) | `Mask::{erode, dilate, open, close}` |
//! | [`mask::xor_count`] | `bitwise_xor`, `countNonZero` | `vt_core::mask::xor_count` |
//! | [`homography::from_correspondences`] | `getPerspectiveTransform` (4 points), `findHomography` (method 0) | `Homography::from_correspondences` |
//! | [`warp::warp_rgb`], [`warp::warp_mask`] | `warpPerspective` | `vt_core::warp::{warp_rgb, warp_mask}` |
//! | [`align::align_backgrounds`] | `pyrDown`, `findTransformECC` per level | `vt_core::align::align_backgrounds` |
//! | [`loops::find_loop`], [`loops::find_loops`] | XOR costs above, `add` + `minMaxLoc` ([`search`]) | `vt_core::loops::{find_loop, find_loops}` (eq. 1) |
//! | [`parallax::estimate`], [`parallax::morph`] | `warpPerspective`, `DISOpticalFlow`, `remap`, `addWeighted` | `vt_core::parallax::{estimate, morph}` |
//! | [`register::register_pair`] | `ORB`, `BFMatcher::knnMatch` (NORM_HAMMING), `findHomography` (RANSAC) | `vt_core::register::register_pair` |
//! | [`yuv::yuv420_to_rgb`] | `cvtColor(COLOR_YUV2RGB_I420)` | `vt_core::yuv::Yuv420Image::to_rgb` |
//! | [`transition::warp_masks`], [`transition::transition_table`] | warps and XOR costs above, `add` + `minMaxLoc` ([`search`]) | `vt_core::transition` (eq. 2) |
#![deny(missing_docs)]

pub mod align;
pub mod blur;
pub mod cases;
pub mod convert;
mod error;
pub mod homography;
pub mod loops;
pub mod mask;
pub mod median;
pub mod parallax;
pub mod register;
pub mod search;
pub mod transition;
pub mod warp;
pub mod yuv;

pub use error::{Error, Result};
