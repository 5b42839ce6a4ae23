//! vt-io: everything vt reads and writes. Videos are decoded by the `ffmpeg` program (Debian's
//! `ffmpeg` package), frame folders by the `image` crate; scene directories are written
//! atomically (a temporary directory renamed into place), so a failed run never leaves a
//! half-written scene where a good one was.
#![deny(missing_docs)]

pub mod atomic;
pub mod display;
mod error;
pub mod frames;
pub mod limits;
pub mod objects;
pub mod output;
pub mod path;
pub mod points;
pub mod scene;
pub mod video;
pub mod writer;

pub use error::{Error, Result};
