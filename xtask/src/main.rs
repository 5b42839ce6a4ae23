//! `cargo xtask`: project chores (lint, benchmarks, the OpenCV cross-check), in Rust so they run
//! wherever cargo does. Few dependencies, so it compiles in seconds.

mod report;

use std::process::Command;

use anyhow::{bail, Context, Result};

const HELP: &str = "\
cargo xtask <task>

tasks:
  lint          cargo fmt --check and cargo clippy (warnings are errors)
  cross-check   run vt-core and vt-cv (OpenCV) on the same inputs and assert they agree
  bench         thesis-scale System A benchmark (decode vs analysis time, peak memory),
                `vt analyze`'s peak memory on 1080p clips of 300 and 600 frames and its
                time against its floor, an exported 720p page's start in headless
                Chromium, then the criterion benches; pass --quick for only a smaller
                thesis-scale scene
  report        [--quick] [--out DIR]: measure every knob's speed/accuracy trade, stability,
                model choice, real-data accuracy and performance against OpenCV; writes
                DIR/index.html (plots beside it), report.json and README.md
                (default DIR: target/report; --quick: about 4 minutes on 2 cores)
";

/// Whether this xtask was built optimised (opt-level 2 or 3: release, or the test command's
/// `checked` profile), so the report can measure in-process.
const OPTIMISED: bool = matches!(env!("XTASK_OPT_LEVEL").as_bytes(), b"2" | b"3");

fn cargo() -> Command {
    Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
}

fn run(mut cmd: Command) -> Result<()> {
    let shown = format!("{cmd:?}");
    let status = cmd.status().with_context(|| format!("running {shown}"))?;
    if !status.success() {
        bail!("{shown} failed ({status})");
    }
    Ok(())
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(task) = args.first() else {
        print!("{HELP}");
        return Ok(());
    };
    let rest = &args[1..];
    match task.as_str() {
        "lint" => {
            let mut fmt = cargo();
            fmt.args(["fmt", "--all", "--", "--check"]);
            run(fmt)?;
            let mut clippy = cargo();
            clippy.args([
                "clippy",
                "--workspace",
                "--all-targets",
                "--",
                "-D",
                "warnings",
            ]);
            run(clippy)
        }
        "cross-check" => {
            let mut c = cargo();
            c.args([
                "run",
                "--release",
                "--quiet",
                "-p",
                "vt-cv",
                "--bin",
                "cross-check",
                "--",
            ])
            .args(rest);
            run(c)
        }
        "bench" => {
            let mut c = cargo();
            c.args(["run", "--release", "--quiet", "-p", "vt-bench", "--"])
                .args(rest);
            run(c)?;
            if !rest.iter().any(|a| a == "--quick") {
                let mut v = cargo();
                v.args(["build", "--release", "--quiet", "-p", "vt-cli"]);
                run(v)?;
                // `vt analyze`'s memory on 1080p clips, and its time against its floor
                // (decode + the store's encode, issue #34), as a user runs it.
                for bin in ["hd-memory", "analyze-floor"] {
                    let mut c = cargo();
                    c.args([
                        "run",
                        "--release",
                        "--quiet",
                        "-p",
                        "vt-bench",
                        "--bin",
                        bin,
                    ]);
                    run(c)?;
                }
                // The exported page's start on a 720p scene in headless Chromium (issue #36).
                let mut p = cargo();
                p.args([
                    "test",
                    "--release",
                    "--quiet",
                    "-p",
                    "vt-cli",
                    "--test",
                    "export",
                    "page_start_720p",
                    "--",
                    "--ignored",
                    "--nocapture",
                ])
                .env("VT_BENCH", "1");
                run(p)?;
                let mut b = cargo();
                b.args(["bench", "-p", "vt-core"]);
                run(b)?;
            }
            Ok(())
        }
        "report" => {
            // Measurements need optimised code: an unoptimised build re-runs itself in release.
            if !OPTIMISED {
                let mut c = cargo();
                c.args(["run", "--release", "--quiet", "-p", "xtask", "--", "report"])
                    .args(rest);
                run(c)
            } else {
                report::run(rest)
            }
        }
        other => {
            print!("{HELP}");
            bail!("unknown task '{other}'")
        }
    }
}
