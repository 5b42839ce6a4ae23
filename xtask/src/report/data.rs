//! Inputs shared by several sections, built once per run on first use: the synthetic System A
//! scene (vt demo's scene) with its truth, analysed and written as a real scene directory; the
//! synthetic System B object; the templeSparseRing photos; tree.avi's frames.

use std::path::Path;
use std::rc::Rc;
use std::time::Instant;

use anyhow::{Context, Result};
use image::RgbImage;
use vt_core::analysis::{AnalyzeParams, MemorySource, SceneAnalysis};
use vt_core::{Mask, Point};
use vt_io::scene::LoadedScene;
use vt_synth::{TextureParams, TextureScene};

use super::Ctx;

/// Analyses in-memory views into a scene directory `dir` (created) through `vt analyze`'s own
/// sequence ([`vt_app::analyze::analyze_into`]: object stores at the default quality, the scene's
/// files, the seams), and loads it back for rendering. Returns the analysis, the seconds of
/// vt-core's analysis and the scene.
/// The analysis parameters of the sections that check System A against source-frame truth
/// (loop lengths in periods, transition phases, the gallery's eq. (1) pictures): the thesis's
/// loops (`--loops single`), whose frames are the source's. A per-region loop (the default
/// where it measures better) is baked into frames of its own.
pub fn thesis_params() -> AnalyzeParams {
    AnalyzeParams {
        regions: None,
        ..Default::default()
    }
}

pub fn build_scene(
    frames: &[Vec<RgbImage>],
    points: &[Vec<Point>],
    params: &AnalyzeParams,
    dir: &Path,
) -> Result<(SceneAnalysis, f64, LoadedScene)> {
    let done = analyze_frames(frames, points, params, dir)?;
    let loaded = LoadedScene::open(dir)?;
    Ok((done.analysis, done.analysis_secs, loaded))
}

/// [`build_scene`]'s analysis, with all its figures (seconds per part).
pub fn analyze_frames(
    frames: &[Vec<RgbImage>],
    points: &[Vec<Point>],
    params: &AnalyzeParams,
    dir: &Path,
) -> Result<vt_app::analyze::Analyzed> {
    analyze_frames_with(frames, points, params, dir, Default::default())
}

/// [`analyze_frames`] with the object stores at `store`.
pub fn analyze_frames_with(
    frames: &[Vec<RgbImage>],
    points: &[Vec<Point>],
    params: &AnalyzeParams,
    dir: &Path,
    store: vt_io::objects::StoreQuality,
) -> Result<vt_app::analyze::Analyzed> {
    std::fs::create_dir_all(dir).with_context(|| dir.display().to_string())?;
    let mut sources: Vec<MemorySource> = frames
        .iter()
        .enumerate()
        .map(|(p, f)| MemorySource {
            name: format!("view {p}"),
            frames: f.clone(),
        })
        .collect();
    let mut refs: Vec<&mut dyn vt_core::analysis::FrameSource> = sources
        .iter_mut()
        .map(|s| s as &mut dyn vt_core::analysis::FrameSource)
        .collect();
    Ok(vt_app::analyze::analyze_into(
        dir,
        &mut refs,
        points,
        params,
        store,
        None,
        &mut vt_app::Silent,
    )?)
}

/// System A's synthetic scene with truth.
pub struct SynthA {
    /// The generator (truth renders, phases, true homographies).
    pub scene: TextureScene,
    /// Every frame of every view, as the cameras recorded them.
    pub frames: Vec<Vec<RgbImage>>,
    /// Exact marked points per view.
    pub points: Vec<Vec<Point>>,
    /// Analysis parameters used (vt's defaults, minimum loop length scaled to the clip).
    pub params: AnalyzeParams,
    /// The analysis with `params`.
    pub analysis: SceneAnalysis,
    /// Seconds of that analysis.
    pub analysis_secs: f64,
    /// The scene as written and loaded back.
    pub loaded: LoadedScene,
    /// True backgrounds per view (no object, no noise, gain 1).
    pub background_truth: Vec<RgbImage>,
    /// True object masks per view and motion phase: pixels where the noise-free render with the
    /// object differs from the background by more than [`TRUTH_MASK_LEVELS`] in some channel.
    pub truth_masks: Vec<Vec<Mask>>,
}

/// Grey levels a noise-free pixel must change by to count as object in the truth masks (an edge
/// pixel half covered by the object changes by about half the object/background contrast).
pub const TRUTH_MASK_LEVELS: u8 = 12;

impl SynthA {
    /// The true object mask of frame `frame` of view `view`.
    pub fn truth_mask(&self, view: usize, frame: usize) -> &Mask {
        &self.truth_masks[view][self.scene.phase_of(view, frame)]
    }

    /// The true background as view `view` records it (its exposure gain applied).
    pub fn background_as_recorded(&self, view: usize) -> RgbImage {
        let g = self.scene.gains()[view];
        let mut out = self.background_truth[view].clone();
        out.pixels_mut()
            .for_each(|p| p.0 = p.0.map(|v| (v as f64 * g).round().clamp(0.0, 255.0) as u8));
        out
    }
}

fn to_rgb(w: u32, h: u32, px: &[[f64; 3]]) -> RgbImage {
    let raw = px
        .iter()
        .flat_map(|p| p.map(|v| v.round().clamp(0.0, 255.0) as u8))
        .collect();
    RgbImage::from_raw(w, h, raw).expect("w*h*3 values")
}

/// The scene's background alone at view `q`: the ray caster with the object's phase NaN, which
/// puts its pose at NaN so that no ray hits it (vt-synth's `shade` tests `e < 1.0`, false for
/// NaN). Checked below against a frame: it must equal the truth render away from the object.
fn background_only(scene: &TextureScene, q: f64) -> RgbImage {
    let p = scene.params();
    to_rgb(p.width, p.height, &scene.render(&scene.camera(q), f64::NAN))
}

/// The parameters of the synthetic System A scene: `vt demo`'s scene (3 views, 320x180, period
/// 24), with fewer frames in a quick run.
pub fn synth_a_params(quick: bool) -> TextureParams {
    TextureParams {
        views: 3,
        frames: if quick { 96 } else { 150 },
        ..Default::default()
    }
}

fn build_synth_a(ctx: &mut Ctx) -> Result<SynthA> {
    let tp = synth_a_params(ctx.quick);
    let scene = TextureScene::new(tp).map_err(anyhow::Error::msg)?;
    let frames: Vec<Vec<RgbImage>> = (0..tp.views)
        .map(|p| (0..tp.frames).map(|s| scene.frame(p, s)).collect())
        .collect();
    let points = scene.marked_points();
    let mut params = thesis_params();
    // Three periods: short enough for the clip, long enough that loops are multiples of it.
    params.loops.min_length = 3 * tp.period;
    let dir = ctx.work.path().join("synth-a-scene");
    let (analysis, analysis_secs, loaded) = build_scene(&frames, &points, &params, &dir)?;
    let background_truth: Vec<RgbImage> = (0..tp.views)
        .map(|p| background_only(&scene, p as f64))
        .collect();
    let truth_masks: Vec<Vec<Mask>> = (0..tp.views)
        .map(|p| {
            (0..tp.period)
                .map(|phase| {
                    // Gain 1, as the background truth: the object alone makes the difference.
                    let with = to_rgb(
                        tp.width,
                        tp.height,
                        &scene.render(&scene.camera(p as f64), phase as f64 / tp.period as f64),
                    );
                    let bg = &background_truth[p];
                    Mask::from_index_fn(tp.width, tp.height, |i| {
                        let (a, b) = (
                            &with.as_raw()[3 * i..3 * i + 3],
                            &bg.as_raw()[3 * i..3 * i + 3],
                        );
                        (0..3).any(|c| a[c].abs_diff(b[c]) > TRUTH_MASK_LEVELS)
                    })
                })
                .collect()
        })
        .collect();
    // The NaN-phase background must really be the background: a truth render agrees with it on
    // most pixels (the object covers a minority of the image at every phase).
    let covered = truth_masks[0][0].count_ones() as f64 / (tp.width * tp.height) as f64;
    anyhow::ensure!(
        covered > 0.005 && covered < 0.5,
        "background-only render is not the background: the object would cover {:.1} % of view 0",
        100.0 * covered
    );
    Ok(SynthA {
        scene,
        frames,
        points,
        params,
        analysis,
        analysis_secs,
        loaded,
        background_truth,
        truth_masks,
    })
}

/// System B's synthetic object (vt-synth's ray-cast sphere + box) with truth at extra angles.
pub struct SynthB {
    /// Photos, cameras (as vt-fv's), masks, and truth for extra viewpoints.
    pub data: vt_synth::object::SynthData<vt_fv::Camera>,
    /// Angles (degrees from camera 0) of the extra viewpoints.
    pub angles: Vec<f64>,
}

fn build_synth_b(ctx: &mut Ctx) -> Result<SynthB> {
    let size = ctx.pick(200, 400);
    let angles = vec![5.0, 10.0];
    let data = vt_synth::object::generate(&vt_synth::object::SceneParams {
        width: size,
        height: size,
        extra_angles_deg: angles.clone(),
        ..Default::default()
    })
    .map_err(anyhow::Error::msg)?
    .try_map_cameras(|c| vt_fv::Camera::new(c.name.clone(), c.k, c.r, c.t))?;
    Ok(SynthB { data, angles })
}

/// System B's default model of the synthetic object and its rough renders at the extra angles,
/// the input of the synthesis knobs.
pub struct SynthBModel {
    /// Grid side used.
    pub grid: usize,
    /// Visual hull + photo hull at the default photo-consistency threshold.
    pub model: vt_fv::VoxelModel,
    /// Rough render at each extra angle.
    pub rough: Vec<RgbImage>,
    /// The reference photo nearest each extra angle.
    pub reference: Vec<usize>,
}

fn build_synth_b_model(ctx: &mut Ctx) -> Result<SynthBModel> {
    let sb = synth_b(ctx)?;
    let d = &sb.data;
    let grid = ctx.pick(128, 256);
    let model = vt_fv::build_model(
        &d.cameras,
        &d.photos,
        &d.masks,
        &vt_fv::hull::HullParams {
            dims: [grid; 3],
            ..Default::default()
        },
        &vt_fv::PhotoParams::default(),
        &mut |_, _, _| {},
    )?;
    let (w, h) = d.photos[0].dimensions();
    let rough = d
        .extra_cameras
        .iter()
        .map(|c| vt_fv::render_rough(&model, c, w, h).image)
        .collect();
    let reference = d
        .extra_cameras
        .iter()
        .map(|c| vt_fv::pipeline::nearest_reference(&d.cameras, c).expect("8 cameras"))
        .collect();
    Ok(SynthBModel {
        grid,
        model,
        rough,
        reference,
    })
}

/// templeSparseRing as shipped in testdata (16 photos), loaded as `vt fv` loads a data folder
/// (vt-fv's `Dataset`: carving silhouettes 3/3 and the Middlebury recipe's for scoring),
/// optionally downscaled.
pub struct Temple {
    /// Photos, cameras, carving and scoring silhouettes.
    pub ds: vt_fv::dataset::Dataset,
    /// Scale applied to the 640x480 photos.
    pub scale: f64,
}

fn build_temple(ctx: &mut Ctx) -> Result<Temple> {
    let scale = ctx.pick(0.5, 1.0);
    let ds = vt_fv::dataset::Dataset::load(
        &super::testdata().join("templeSparseRing"),
        &vt_fv::dataset::DataOptions {
            scale,
            ..Default::default()
        },
    )?;
    Ok(Temple { ds, scale })
}

/// tree.avi's frames (a real 320x240 video of a tree in wind, static camera).
pub struct Tree {
    /// Every decoded frame.
    pub frames: Vec<RgbImage>,
    /// Seconds to decode them (ffmpeg through vt-io).
    pub decode_secs: f64,
}

fn build_tree() -> Result<Tree> {
    use vt_core::analysis::FrameSource;
    let path = super::testdata().join("tree.avi");
    let mut src = vt_io::frames::VideoSource::open(&path)?;
    let mut frames = Vec::new();
    let t = Instant::now();
    src.for_each_frame(&mut |_, f| {
        frames.push(f.clone());
        Ok(())
    })?;
    Ok(Tree {
        frames,
        decode_secs: t.elapsed().as_secs_f64(),
    })
}

/// System A's real-footage scene: tree.avi on a slanted plane seen by cameras on a line, with
/// known homographies and clock offsets (vt-synth's `RealScene`), 2 px marking noise.
pub struct Real {
    /// The generator (truth).
    pub scene: vt_synth::real::RealScene,
    /// Every frame of every view.
    pub frames: Vec<Vec<RgbImage>>,
    /// The marked points (with noise).
    pub points: Vec<Vec<Point>>,
}

/// Parameters of the real-footage scene.
pub fn real_params(quick: bool) -> vt_synth::real::RealParams {
    vt_synth::real::RealParams {
        views: if quick { 3 } else { 5 },
        frames: if quick { 80 } else { 120 },
        marking_noise: 2.0,
        ..Default::default()
    }
}

fn build_real(ctx: &mut Ctx) -> Result<Real> {
    let tr = tree(ctx)?;
    let rp = real_params(ctx.quick);
    let scene =
        vt_synth::real::RealScene::new(tr.frames.clone(), rp).map_err(anyhow::Error::msg)?;
    let frames = (0..rp.views)
        .map(|v| (0..rp.frames).map(|s| scene.frame(v, s)).collect())
        .collect();
    let points = (0..rp.views)
        .map(|v| {
            scene
                .marked_points(v)
                .into_iter()
                .map(|(x, y)| Point::new(x, y))
                .collect()
        })
        .collect();
    Ok(Real {
        scene,
        frames,
        points,
    })
}

/// The lazily built inputs.
#[derive(Default)]
pub struct Cache {
    synth_a: Option<Rc<SynthA>>,
    synth_b: Option<Rc<SynthB>>,
    temple: Option<Rc<Temple>>,
    tree: Option<Rc<Tree>>,
    synth_b_model: Option<Rc<SynthBModel>>,
    real: Option<Rc<Real>>,
}

/// Builds (once) and returns an input.
macro_rules! getter {
    ($name:ident, $ty:ty, $build:expr) => {
        /// The shared input, built on first use.
        pub fn $name(ctx: &mut Ctx) -> Result<Rc<$ty>> {
            if ctx.data.$name.is_none() {
                let t = Instant::now();
                let built = $build(ctx).context(stringify!($name))?;
                eprintln!(
                    "report:   built {} in {:.1} s",
                    stringify!($name),
                    t.elapsed().as_secs_f64()
                );
                ctx.data.$name = Some(Rc::new(built));
            }
            Ok(ctx.data.$name.clone().expect("built above"))
        }
    };
}

getter!(synth_a, SynthA, build_synth_a);
getter!(synth_b, SynthB, build_synth_b);
getter!(temple, Temple, build_temple);
getter!(tree, Tree, |_: &mut Ctx| build_tree());
getter!(synth_b_model, SynthBModel, build_synth_b_model);
getter!(real, Real, build_real);
