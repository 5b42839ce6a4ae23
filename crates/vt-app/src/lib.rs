//! vt-app: vt's use cases, one typed function each, with a parameter struct, a [`Progress`]
//! observer and one error type. The `vt` binary is argument parsing, progress bars and printing
//! over these functions; the CLI tests and `cargo xtask report` call the same functions, so what
//! the report measures is what users run.
//!
//! | use case | function | `vt` command |
//! | --- | --- | --- |
//! | videos (or in-memory frames) into a scene | [`analyze::analyze`], [`analyze::analyze_into`] | `vt analyze` |
//! | a viewpoint path played into frames | [`play::play`] | `vt render`, `vt export`'s checks |
//! | a viewpoint path rendered into a file | [`render::render`] | `vt render` |
//! | a scene as a web page | [`export::export`] | `vt export` |
//! | the whole of System A on a built-in scene, checked | [`demo::demo`] | `vt demo` |
//! | a scene served live | [`view::open`] | `vt view` |
//! | test views with truth from one real video | [`synth::real`] | `vt synth real` |
//! | photos into a voxel model | [`fv::hull`] | `vt fv hull` |
//! | a new view, an orbit, withheld views scored | [`fv::render`], [`fv::orbit`], [`fv::eval`] | `vt fv render`, `orbit`, `eval` |
//!
//! Rules about parameters live with the parameter types (`AnalyzeParams::check`,
//! `RenderParams::check`, `EncodeParams::check`, ...) and each job's own `check`; every error
//! names the parameter (`Error::Param`'s `name`, or vt-core's `InvalidParameter`), which the
//! binary maps to its flag.

pub mod analyze;
pub mod demo;
mod error;
pub mod export;
pub mod fv;
pub mod play;
mod progress;
pub mod render;
pub mod synth;
pub mod view;

pub use error::{Error, Result};
pub use progress::{Progress, Silent};
