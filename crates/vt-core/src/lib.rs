//! vt-core: every algorithm of vt in pure Rust, with no I/O and no OpenCV.
//!
//! System A (viewpoint-varying video textures, seed thesis Sec. 3) offline analysis:
//! [`median`] backgrounds, [`blur`], [`mask`] extraction by background subtraction,
//! [`loops`] (eq. 1), [`homography`] and [`model`] selection between views, [`warp`] of masks,
//! [`transition`] tables (eq. 2), and the [`analysis`] pipeline that ties them together;
//! online, [`render`] (eq. 3-6): the source-frame player and the intermediate-view renderer.
//!
//! Images are the `image` crate's [`image::RgbImage`]; pixel centres sit at integer
//! coordinates `(x, y) = (column, row)`, origin top-left, as in OpenCV.
#![deny(missing_docs)]

pub mod analysis;
pub mod blur;
mod error;
pub mod homography;
pub mod loops;
pub mod mask;
pub mod median;
pub mod model;
pub mod render;
pub mod transition;
pub mod warp;

pub use error::{Error, Result};
pub use homography::{Homography, Point};
pub use mask::Mask;
