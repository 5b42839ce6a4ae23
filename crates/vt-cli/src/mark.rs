//! `vt mark`: parses the arguments and serves vt-view's marking page (routes, limits and the
//! page are documented in `crates/vt-view/src/mark.rs`).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{anyhow, Result};
use clap::Args;
use vt_view::mark::{Marker, Session};

#[derive(Args)]
pub struct MarkArgs {
    /// One scene directory written by `vt analyze`, or two or more views (videos or frame
    /// folders) in camera order.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Points file to save to (written atomically; only a points file vt wrote is replaced).
    #[arg(long)]
    out: PathBuf,
    /// Port on 127.0.0.1 (0 = any free port; the URL is printed).
    #[arg(long, default_value_t = 8080)]
    port: u16,
    /// Points file to start from (instead of the scene's points).
    #[arg(long)]
    points: Option<PathBuf>,
}

pub fn run(args: MarkArgs) -> Result<()> {
    let session = Session::open(&args.inputs, args.points.as_deref(), &args.out)?;
    let (m, k) = (session.views(), session.points()[0].len());
    let marker = Marker::bind(session, args.port).map_err(|e| match e {
        vt_view::Error::Listen { port, cause } => {
            anyhow!("--port {port}: cannot listen on 127.0.0.1: {cause}")
        }
        e => e.into(),
    })?;
    println!(
        "vt mark: marking {m} views ({k} points) at http://127.0.0.1:{}/ ; Save writes {} (Ctrl-C to stop)",
        marker.port(),
        args.out.display()
    );
    std::io::stdout().flush().ok();
    marker.serve();
    Ok(())
}
