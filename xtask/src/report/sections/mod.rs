//! The report's sections, in page order. Section 1 is a list of knobs: each a function returning
//! its curve(s), or a plain statement that it does not exist yet.

pub mod benchmark;
pub mod gallery;
pub mod knobs_a;
pub mod knobs_a_real;
pub mod knobs_b;
pub mod models;
pub mod perf;
pub mod real;
pub mod stability;

use anyhow::Result;

use super::model::{Curve, Item};
use super::Ctx;

/// Measures one knob.
pub type Measure = fn(&mut Ctx) -> Result<Vec<Curve>>;

/// One knob of section 1.
pub struct Knob {
    /// Its name on the page.
    pub title: &'static str,
    /// The measurement, or why there is none.
    pub measure: Result<Measure, &'static str>,
}

impl Knob {
    /// A measured knob.
    pub fn new(title: &'static str, measure: Measure) -> Self {
        Self {
            title,
            measure: Ok(measure),
        }
    }

    /// A knob that does not exist yet, and why (listed on the page as "not yet implemented").
    #[allow(dead_code)]
    pub fn missing(title: &'static str, why: &'static str) -> Self {
        Self {
            title,
            measure: Err(why),
        }
    }
}

fn curves(ctx: &mut Ctx) -> Result<Vec<Item>> {
    let mut items = vec![Item::Note {
        text: "System A first (on the synthetic scene of `vt demo`, whose truth is known \
               exactly), then System B (on vt-fv's synthetic object, truth rendered at 5 and 10 \
               degrees from camera 0)."
            .into(),
    }];
    let mut failed = Vec::new();
    let knobs: Vec<Knob> = knobs_a::knobs()
        .into_iter()
        .chain(knobs_a_real::knobs())
        .chain(knobs_b::knobs())
        .filter(|k| ctx.wants(k.title))
        .collect();
    for knob in knobs {
        match knob.measure {
            Ok(f) => match timed(knob.title, || f(ctx)) {
                Ok(cs) => items.extend(cs.into_iter().map(Item::Curve)),
                Err(e) => {
                    failed.push(format!("{}: {e:#}", knob.title));
                    items.push(Item::Missing {
                        title: knob.title.into(),
                        why: format!("the measurement failed: {e:#}"),
                    });
                }
            },
            Err(why) => items.push(Item::Missing {
                title: knob.title.into(),
                why: why.into(),
            }),
        }
    }
    if !failed.is_empty() {
        anyhow::bail!("knobs failed: {}", failed.join("; "));
    }
    Ok(items)
}

/// Runs one part of a section (a knob's curves, one of section 4's tables) and prints its time,
/// so a slow report (and the test that runs it) says where its time goes.
pub fn timed<T>(title: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
    let t = std::time::Instant::now();
    let out = f();
    eprintln!("report:   {title}: {:.1} s", t.elapsed().as_secs_f64());
    out
}

/// A section builder.
pub type Build = fn(&mut Ctx) -> Result<Vec<Item>>;

/// Every section: (anchor, title, intro, builder).
pub fn all() -> Vec<(&'static str, &'static str, &'static str, Build)> {
    vec![
        (
            "curves",
            "1. Speed/accuracy curves",
            "One plot per knob: time (or speed) on one axis, an error measured against truth on the \
             other, every setting a point.",
            curves,
        ),
        (
            "stability",
            "2. Stability at the extremes",
            "What vt-core and OpenCV do with degenerate and non-finite input, and whether the \
             renderer is continuous in the viewpoint q where its formulas switch cases.",
            stability::build,
        ),
        (
            "models",
            "3. Model only what the scene requires",
            "vt picks the simplest geometric model (translation, similarity, affine, homography) \
             that explains the marked points, by GRIC. Which model each scene gets, and what the \
             wrong choice costs in rendered PSNR.",
            models::build,
        ),
        (
            "real",
            "4. Accuracy on real data",
            "System A's transitions and homographies against known truth, and System B's \
             leave-one-out on the real templeSparseRing photos.",
            real::build,
        ),
        (
            "benchmark",
            "4b. The field's benchmark for System B",
            "NeRF synthetic lego from 8 views, the sparse-view protocol every paper since 2021 \
             reports: vt's row measured here beside the published ones, and the stereo \
             carving's knobs.",
            benchmark::build,
        ),
        (
            "gallery",
            "5. Gallery",
            "What the numbers look like.",
            gallery::build,
        ),
        (
            "performance",
            "6. Performance",
            "Measured side by side in this run, on this machine; ratios first.",
            perf::build,
        ),
    ]
}
