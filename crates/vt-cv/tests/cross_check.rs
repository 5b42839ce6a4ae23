//! The whole cross-check (`cargo xtask cross-check`) as a test: the `cross-check` binary built
//! with this test, run from the workspace root, must pass every row. Ignored by a plain `cargo
//! test` (a minute optimised, far longer unoptimised); `scripts/test-all` runs it with the
//! other ignored tests from its one optimised build. On failure the table is printed, with the
//! images of each failing row under `target/cross-check/`.

use std::path::Path;
use std::process::Command;

#[test]
#[ignore = "a minute optimised: cargo test --profile checked -p vt-cv --test cross_check -- --ignored, or cargo xtask cross-check"]
fn vt_core_agrees_with_opencv_on_every_row() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let out = Command::new(env!("CARGO_BIN_EXE_cross-check"))
        .current_dir(&root)
        .output()
        .expect("run the cross-check");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "the cross-check failed ({}):\n{stdout}\n{stderr}",
        out.status
    );
    // The summary line: "N checks, 0 failed, T s".
    let summary = stdout
        .lines()
        .rfind(|l| l.contains(" checks, "))
        .unwrap_or("");
    assert!(summary.contains(" 0 failed"), "{summary}\n{stdout}");
    eprintln!("{summary}");
}
