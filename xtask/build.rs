//! Tells xtask how optimised the profile that built it is: the report measures only optimised
//! code, and an unoptimised xtask re-runs itself in release.

fn main() {
    let opt = std::env::var("OPT_LEVEL").unwrap_or_default();
    println!("cargo:rustc-env=XTASK_OPT_LEVEL={opt}");
    println!("cargo:rerun-if-changed=build.rs");
}
