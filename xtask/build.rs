//! Tells xtask which Cargo profile built it and how optimised that is: the cross-check it runs
//! is built with the same profile, and the report measures only optimised code.

use std::path::Path;

fn main() {
    let opt = std::env::var("OPT_LEVEL").unwrap_or_default();
    // OUT_DIR is target/[triple/]<profile dir>/build/xtask-<hash>/out, and the profile dir is
    // "debug" for dev and the profile's own name for the others.
    let out = std::env::var("OUT_DIR").unwrap_or_default();
    let dir = Path::new(&out)
        .ancestors()
        .nth(3)
        .and_then(Path::file_name)
        .and_then(|n| n.to_str())
        .unwrap_or("debug");
    let profile = if dir == "debug" { "dev" } else { dir };
    println!("cargo:rustc-env=XTASK_PROFILE={profile}");
    println!("cargo:rustc-env=XTASK_OPT_LEVEL={opt}");
    println!("cargo:rerun-if-changed=build.rs");
}
