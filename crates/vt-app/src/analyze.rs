//! Videos (or frame folders, or frames in memory) into a scene directory: System A's offline half
//! (`vt analyze`), in one sequence that the binary, the tests and the report share.
//!
//! [`analyze`] opens the views, checks their sizes and the points before any work, writes the
//! scene atomically ([`vt_io::output`]) and commits it only when everything succeeded.
//! [`analyze_into`] is the same sequence from frame sources into a directory the caller owns:
//! vt-core's analysis with the object stores written as the masks arrive, the scene's files, and
//! the seams measured on rendered frames ([`record_seams`]).

use std::path::{Path, PathBuf};
use std::time::Instant;

use image::RgbImage;
use vt_core::analysis::{AnalyzeParams, FrameSource, Observer, SceneAnalysis, Stage};
use vt_core::{Mask, Point};
use vt_io::frames::ViewSource;
use vt_io::objects::{StoreQuality, StoreWriter};
use vt_io::output::{Output, OutputKind};
use vt_io::scene::{LoadedScene, SceneFile};

use crate::{Error, Progress, Result};

/// `vt analyze`'s job: the views, the optional points file, where the scene goes and how.
#[derive(Debug, Clone)]
pub struct AnalyzeJob {
    /// One video or frame folder per view, in camera order.
    pub views: Vec<PathBuf>,
    /// The points file (without it, neighbouring views are registered automatically).
    pub points: Option<PathBuf>,
    /// The scene directory to write (replaced only if it is vt's own scene).
    pub out: PathBuf,
    /// The analysis's parameters.
    pub params: AnalyzeParams,
    /// The source frame rate to record (None: the videos' median real frame rate; frame
    /// folders have none).
    pub fps: Option<f64>,
    /// How the object stores keep the pixels.
    pub store: StoreQuality,
}

/// Highest frame rate a scene records, frames per second.
pub const MAX_FPS: f64 = 1000.0;

impl AnalyzeJob {
    /// Checks the parameters ([`AnalyzeParams::check`]) and the frame rate.
    pub fn check(&self) -> Result<()> {
        self.params.check()?;
        if let Some(fps) = self.fps {
            if !(fps.is_finite() && fps > 0.0 && fps <= MAX_FPS) {
                return Err(Error::Param {
                    name: "fps",
                    value: fps.to_string(),
                    why: format!("a frame rate above 0 and at most {MAX_FPS} frames per second"),
                });
            }
        }
        if self.views.len() > vt_io::limits::MAX_VIEWS {
            return Err(Error::Param {
                name: "views",
                value: self.views.len().to_string(),
                why: format!("at most {} views", vt_io::limits::MAX_VIEWS),
            });
        }
        Ok(())
    }
}

/// What an analysis produced.
pub struct Analyzed {
    /// vt-core's analysis.
    pub analysis: SceneAnalysis,
    /// The scene.json written.
    pub scene: SceneFile,
    /// Seconds of vt-core's analysis alone (decoding included, writing excluded).
    pub analysis_secs: f64,
    /// Seconds of measuring the seams on rendered frames ([`record_seams`]).
    pub seams_secs: f64,
    /// Seconds of the whole use case.
    pub total_secs: f64,
    /// Per view, what the object store's quality target chose (None: lossless or a fixed
    /// quantiser).
    pub stores: Vec<Option<vt_io::objects::TargetChoice>>,
}

/// Analyses `job.views` into the scene `job.out`: parameters, views, sizes and points are
/// checked before any work; the scene appears only when complete.
pub fn analyze(job: &AnalyzeJob, progress: &mut dyn Progress) -> Result<Analyzed> {
    let started = Instant::now();
    job.check()?;
    let m = job.views.len();
    // The views are probed side by side, a few at a time (an ffprobe each, which reads the
    // video's packets for its real frame rate: mostly the program's start-up).
    let mut opened: Vec<Result<(ViewSource, Option<f64>)>> = Vec::with_capacity(m);
    for (k, chunk) in job.views.chunks(PROBES_AT_ONCE).enumerate() {
        std::thread::scope(|scope| {
            let probes: Vec<_> = chunk
                .iter()
                .enumerate()
                .map(|(i, path)| {
                    let view = k * PROBES_AT_ONCE + i;
                    scope.spawn(move || {
                        ViewSource::open_timed(path)
                            .map_err(|cause| Error::OpenView { view, cause })
                    })
                })
                .collect();
            opened.extend(probes.into_iter().map(|p| {
                p.join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
            }));
        });
    }
    let (mut sources, rates): (Vec<ViewSource>, Vec<Option<f64>>) = opened
        .into_iter()
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .unzip();
    for (path, source) in job.views.iter().zip(&sources) {
        for note in source.notes() {
            progress.note(&format!("{}: {note}", path.display()));
        }
    }
    // Sizes are known before decoding: refuse mismatched views before any work.
    let size = vt_io::frames::common_size(&job.views, &sources)?;
    let points = match &job.points {
        Some(path) => vt_io::points::read_for_views(path, m, size)?,
        None => Vec::new(),
    };
    let mut inputs: Vec<&Path> = job.views.iter().map(PathBuf::as_path).collect();
    inputs.extend(job.points.as_deref());
    let dir = Output::dir(&job.out, OutputKind::Scene, &inputs)?;
    let fps = job.fps.or_else(|| vt_io::video::views_frame_rate(rates));
    let mut refs: Vec<&mut dyn FrameSource> = sources.iter_mut().map(|s| s.as_source()).collect();
    let mut out = analyze_into(
        dir.path(),
        &mut refs,
        &points,
        &job.params,
        job.store,
        fps,
        progress,
    )
    .map_err(|e| match (e, &job.points) {
        // Points that fit no model: the points file is what to fix.
        (
            Error::Core(c @ (vt_core::Error::DegeneratePoints(_) | vt_core::Error::NonFinite(_))),
            Some(p),
        ) => Error::Input {
            path: p.clone(),
            cause: Box::new(Error::Core(c)),
        },
        (e, _) => e,
    })?;
    dir.commit()?;
    out.total_secs = started.elapsed().as_secs_f64();
    Ok(out)
}

/// Views probed at once when a job opens them.
const PROBES_AT_ONCE: usize = 8;

/// Analyses `sources` (one per view, in order) with `points[p]` view p's marked points (empty:
/// registered automatically) into `dir`, an existing directory the caller owns: the object
/// stores at `store` as the masks arrive, the backgrounds, dynamic regions, fit pictures and
/// parallax fields, and scene.json with the source frame rate `fps` and the seams measured on
/// rendered frames.
pub fn analyze_into(
    dir: &Path,
    sources: &mut [&mut dyn FrameSource],
    points: &[Vec<Point>],
    params: &AnalyzeParams,
    store: StoreQuality,
    fps: Option<f64>,
    progress: &mut dyn Progress,
) -> Result<Analyzed> {
    let started = Instant::now();
    params.check()?;
    let mut observer = Stores {
        stores: StoreWriter::with_quality(dir, store),
        progress,
        done: 0,
    };
    let analysis = vt_core::analysis::analyze(sources, points, params, &mut observer);
    Observer::finish(&mut observer);
    let analysis = analysis.map_err(|e| match e {
        // The way out: a shorter minimum loop.
        vt_core::Error::TooFewFrames { got, .. } if got > params.loops.window => Error::TooShort {
            cause: e,
            max_min_length: got - params.loops.window,
        },
        e => e.into(),
    })?;
    let analysis_secs = started.elapsed().as_secs_f64();
    observer.stores.finish()?;
    let mut scene = vt_io::scene::write_analysis(dir, &analysis, params, fps)?;
    // The seams as a render shows them, now that there is a scene to render.
    observer.progress.start("seams", None);
    let seams_started = Instant::now();
    record_seams(dir, &mut scene)?;
    let seams_secs = seams_started.elapsed().as_secs_f64();
    observer.progress.finish();
    scene.write(dir)?;
    Ok(Analyzed {
        analysis,
        scene,
        analysis_secs,
        seams_secs,
        total_secs: started.elapsed().as_secs_f64(),
        stores: observer.stores.choices().to_vec(),
    })
}

/// The analysis observer: object stores written as masks arrive, stages reported to `progress`.
struct Stores<'a> {
    stores: StoreWriter,
    progress: &'a mut dyn Progress,
    done: u64,
}

impl Observer for Stores<'_> {
    fn start(&mut self, stage: Stage, view: Option<usize>, total: Option<u64>) {
        let name = match view {
            Some(p) => format!("view {p}: {stage}"),
            None => stage.to_string(),
        };
        self.done = 0;
        self.progress.start(&name, total);
    }

    fn tick(&mut self) {
        self.done += 1;
        self.progress.at(self.done, None);
    }

    fn finish(&mut self) {
        self.progress.finish();
    }

    fn object_frame(
        &mut self,
        view: usize,
        frame: usize,
        mask: &Mask,
        raw: &RgbImage,
    ) -> vt_core::Result<()> {
        self.stores.object_frame(view, frame, mask, raw)
    }
}

/// Measures the scene in `dir` ([`vt_core::seam::measure_seams`] on frames its renderer makes
/// with default settings) and records the seams in `scene`: each view's `loop_seam`, each link's
/// `seam` (the mean of its two directions, 0 when neither has a transition) and `seam_score`
/// (the mean over wraps and links), the one seam score `vt render` also prints.
pub fn record_seams(dir: &Path, scene: &mut SceneFile) -> Result<()> {
    let loaded = LoadedScene::open(dir)?;
    let seams = vt_core::seam::measure_seams(
        &loaded.render,
        &loaded.objects,
        vt_core::render::RenderParams::default(),
        vt_core::seam::SeamSampling::default(),
    )?;
    let mut all = Vec::new();
    for (p, v) in seams.iter().enumerate() {
        let wrap = v.wrap.unwrap_or(0.0);
        scene.views[p].loop_seam = wrap;
        all.push(wrap);
        if p + 1 < seams.len() {
            let both: Vec<f64> = v.to_next.into_iter().chain(seams[p + 1].to_prev).collect();
            let link = both.iter().sum::<f64>() / both.len().max(1) as f64;
            if let Some(l) = scene.views[p].to_next.as_mut() {
                l.seam = link;
            }
            if let Some(l) = scene.views[p + 1].to_prev.as_mut() {
                l.seam = link;
            }
            all.push(link);
        }
    }
    scene.seam_score = all.iter().sum::<f64>() / all.len().max(1) as f64;
    Ok(())
}

/// `vt analyze`'s summary of an analysis: one table row per view (frames, loop, cost, seams,
/// moving share, model, point rms), the seam score, motion kept, the model selection and the
/// time per stage.
pub struct AnalysisSummary<'a> {
    /// The analysis.
    pub analysis: &'a vt_core::analysis::SceneAnalysis,
    /// Its scene.json (seams and point residuals of the links).
    pub scene: &'a SceneFile,
    /// Wall time of the whole run, seconds.
    pub total_secs: f64,
    /// Of which measuring the seams on rendered frames.
    pub seams_secs: f64,
    /// Per view, what the object store's quality target chose ([`Analyzed::stores`]).
    pub stores: &'a [Option<vt_io::objects::TargetChoice>],
}

impl std::fmt::Display for AnalysisSummary<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (a, scene, total_s) = (self.analysis, self.scene, self.total_secs);
        let seams_s = self.seams_secs;
        writeln!(
            f,
            "{:>4}  {:>6}  {:>12}  {:>6}  {:>10}  {:>9}  {:>11}  {:>7}  {:>9}  {:>8}",
            "view",
            "frames",
            "loop (m, n)",
            "length",
            "cost",
            "loop seam",
            "switch seam",
            "moving",
            "model",
            "rms px"
        )?;
        let model = a.model().map(|m| m.name()).unwrap_or("-");
        for (p, v) in a.views.iter().enumerate() {
            let rms = scene.views[p]
                .to_next
                .as_ref()
                .map(|l| format!("{:.3}", l.rms))
                .unwrap_or_else(|| "-".into());
            let switch = scene.views[p]
                .to_next
                .as_ref()
                .map(|l| format!("{:.3}", l.seam))
                .unwrap_or_else(|| "-".into());
            writeln!(
                f,
                "{:>4}  {:>6}  {:>12}  {:>6}  {:>10}  {:>9.3}  {:>11}  {:>6.1}%  {:>9}  {:>8}",
                p,
                v.n_frames,
                format!("({}, {})", v.best_loop.start, v.best_loop.end),
                v.best_loop.len(),
                v.best_loop.cost,
                scene.views[p].loop_seam,
                switch,
                100.0 * v.moving_fraction,
                if p + 1 < a.views.len() { model } else { "-" },
                rms
            )?;
        }
        writeln!(f,
        "seam score (mean over wraps and switches, on rendered frames as vt render measures them: a wrap against the median ordinary step, a switch and its fade against the steps it replaced; 1 = no larger than ordinary playback, above 1 shows): {:.3}",
        scene.seam_score
    )?;
        for (p, v) in a.views.iter().enumerate() {
            if let Some(shake) = v.shake.as_ref().filter(|s| {
                matches!(
                    s.verdict,
                    vt_core::stabilize::Verdict::Steadied
                        | vt_core::stabilize::Verdict::Untextured
                        | vt_core::stabilize::Verdict::Unanchored
                )
            }) {
                writeln!(f, "view {p}: {}", shake.describe())?;
            }
            if let Some(bytes) = v.regions_over_cache {
                writeln!(f,
                    "view {p}: no per-region loop: the source frames around its loop, packed, their label search and the view's masks need about {} MiB, over the frame cache (--cache-mb); it keeps the thesis's loop (raise --cache-mb to at least {} for per-region loops)",
                    bytes.div_ceil(1 << 20), bytes.div_ceil(1 << 20)
                )?;
            }
            if let Some(q) = &v.region_not_needed {
                writeln!(f,
                    "view {p}: no per-region loop needed: the thesis's loop's tiles wrap at {:.2}x their ordinary step (median inside the dynamic region)",
                    q.tile_wrap
                )?;
            }
            if let Some(res) = &v.region_rejected {
                writeln!(f,
                    "view {p}: per-region loop not kept: its tile wraps, {:.2}x their ordinary step (90th percentile {:.2}x), are no better than the thesis's loop's {:.2}x ({:.2}x) measured alike inside the dynamic region; it keeps the thesis's loop (--loops regions keeps it anyway); tried in {:.2} s",
                    res.quality.tile_wrap, res.quality.tile_wrap_p90, res.single.tile_wrap, res.single.tile_wrap_p90, res.secs
                )?;
            }
            if let Some(res) = &v.region_loop {
                let (r, q, one) = (&res.chosen, &res.quality, &res.single);
                writeln!(f,
                    "view {p}: per-region loop of {} frames, {} tiles of {} px, periods {:?}; energy {:.3e} (best single label {:.3e}); inside the dynamic region: worst step {:.2}x the median, tile wraps {:.2}x (90th percentile {:.2}x), sharpness {:.3} of the source's ({:.3} near the tile wraps), {:.2} grey levels from the nearest source frame per tile; the thesis's loop measured alike: worst step {:.2}x, tile wraps {:.2}x ({:.2}x), sharpness {:.3} ({:.3} near its wrap); baked in {:.2} s",
                    r.length, r.labels.len(), r.tile, r.periods, r.energy, r.single_energy,
                    q.worst_step, q.tile_wrap, q.tile_wrap_p90, q.sharpness, q.sharpness_near, q.source_error, one.worst_step, one.tile_wrap, one.tile_wrap_p90, one.sharpness, one.sharpness_near, res.secs
                )?;
            }
        }
        let kept: Vec<String> = a
            .views
            .iter()
            .map(|v| format!("{:.1}%", 100.0 * v.motion_kept))
            .collect();
        let dynamic: Vec<String> = a
            .views
            .iter()
            .map(|v| format!("{:.1}%", 100.0 * v.dynamic_fraction))
            .collect();
        writeln!(f,
        "motion kept (share of the real frame-to-frame change shown at each view): {}; dynamic region: {} of the image",
        kept.join(" "),
        dynamic.join(" ")
    )?;
        if let Some(sel) = &a.selection {
            let scores: Vec<String> = sel
                .scores
                .iter()
                .map(|(m, s)| format!("{m} {s:.1}"))
                .collect();
            writeln!(
                f,
                "model: {}{} (GRIC: {}){}",
                sel.model,
                if sel.forced { ", forced" } else { "" },
                scores.join(", "),
                if sel.sigma < scene.params.model.sigma {
                    format!(
                        "; scored at marking noise {:.2} px, what the points' own residuals imply (--point-sigma {} assumes more)",
                        sel.sigma, scene.params.model.sigma
                    )
                } else {
                    String::new()
                }
            )?;
        }
        for (p, r) in a.registration.iter().enumerate() {
            let rest = if r.rest_inliers.1 > 0 {
                format!(
                    "; the rest of the background fits it at {} of {} matches ({:.0}%)",
                    r.rest_inliers.0,
                    r.rest_inliers.1,
                    100.0 * r.rest_inliers.0 as f64 / r.rest_inliers.1 as f64
                )
            } else {
                String::new()
            };
            let object = match a.object_planes.get(p).copied().flatten() {
                Some(o) if o.kept => format!(
                    "; plane used: the moving object's own ({}, its silhouettes' error {:.2} -> {:.2})",
                    o.model, o.error_before, o.error_after
                ),
                Some(o) => format!(
                    "; plane used: the background's (the moving object's silhouettes agree: {:.2}, own plane {:.2})",
                    o.error_before, o.error_after
                ),
                None => "; plane used: the background's (nothing moves)".into(),
            };
            writeln!(
                f,
                "registered {p}->{}: background plane {}{}, {} inliers of {} matches in {} of 64 cells, residual {:.2} px{rest}{object}; see {}",
                p + 1,
                r.plane,
                if r.epipolar.is_some() {
                    " (parallax: a plane the views' epipolar geometry allows, shared by the links)"
                } else {
                    ""
                },
                r.inliers.len(),
                r.matches,
                r.cells,
                r.rms,
                vt_io::scene::fit_name(p)
            )?;
        }
        for (p, l) in a.links.iter().enumerate() {
            if let Some(fig) = &l.parallax_figures {
                let how = if fig.morph {
                    format!(
                        "morph along the dense parallax ({:.0}% of the pixels confirmed by both views; {})",
                        100.0 * fig.confirmed,
                        vt_io::scene::parallax_name(p, 0)
                    )
                } else {
                    "the plane (the rest lies on it)".into()
                };
                writeln!(
                    f,
                    "background {p}->{}: parallax off the plane {:.1} px (90th percentile of the matches); {how}",
                    p + 1,
                    fig.residual_px
                )?;
            }
        }
        if let Some(target) = self.stores.iter().flatten().next().map(|c| c.target_db) {
            let list = |v: Vec<String>| v.join(" ");
            let qps = list(
                self.stores
                    .iter()
                    .map(|c| c.map_or("-".into(), |c| c.qp.to_string()))
                    .collect(),
            );
            let dbs = list(
                self.stores
                    .iter()
                    .map(|c| c.map_or("-".into(), |c| format!("{:.1}", c.predicted_db)))
                    .collect(),
            );
            let short: Vec<String> = self
                .stores
                .iter()
                .enumerate()
                .filter(|(_, c)| c.is_some_and(|c| c.predicted_db < c.target_db as f64))
                .map(|(p, _)| p.to_string())
                .collect();
            write!(
                f,
                "object stores: H.264 at quantisers {qps}, the coarsest predicted to keep \
                 {target} dB under the masks (predicted {dbs} dB)"
            )?;
            if short.is_empty() {
                writeln!(f)?;
            } else {
                writeln!(
                    f,
                    "; view {} falls short even at the finest quantiser (--store-quality \
                     lossless keeps every pixel)",
                    short.join(", ")
                )?;
            }
        }
        let vt_core::analysis::Timings {
            decode,
            median,
            masks,
            loops,
            homographies,
            transitions,
            parallax,
            shake,
        } = a.timings;
        writeln!(f,
        "time: {total_s:.2} s (shake {:.2}, decode {:.2}, median {:.2}, masks {:.2}, loops {:.2}, homographies {:.3}, transitions {:.2}, parallax {:.2}, seams {seams_s:.2})",
        shake.as_secs_f64(),
        decode.as_secs_f64(),
        median.as_secs_f64(),
        masks.as_secs_f64(),
        loops.as_secs_f64(),
        homographies.as_secs_f64(),
        transitions.as_secs_f64(),
        parallax.as_secs_f64()
    )?;
        Ok(())
    }
}
