//! The random generator: vt-core's SplitMix64, the workspace's one RNG.

pub use vt_core::rng::Rng;
