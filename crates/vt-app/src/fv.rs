//! System B's use cases (`vt fv hull|render|orbit|eval`): calibrated photos into a voxel model,
//! new views from it, an orbit video, and withheld views scored. Each loads the data folder,
//! builds the model once (or reads `vt fv hull`'s model file) and makes its views by the same
//! default method.

use std::path::{Path, PathBuf};
use std::time::Instant;

use vt_fv::camera::Ring;
use vt_fv::composite::Background;
use vt_fv::dataset::{
    read_model, write_eval_images, write_hull, write_json, write_test_outputs, BuildSummary,
    DataOptions, Dataset, EvalSummary, ModelParams, SilhouetteCheck, TestSummary,
};
use vt_fv::hull::Aabb;
use vt_fv::modelfile::ModelHeader;
use vt_fv::orbit::Steadiness;
use vt_fv::pipeline::EvalReport;
use vt_fv::pipeline::{novel_view_in, ViewOptions};
use vt_fv::texture::model_centre;
use vt_fv::VoxelModel;
use vt_io::output::{Output, OutputKind};

use crate::{Error, Progress, Result};

/// Where the photos, cameras and silhouettes come from, and how the model is made.
#[derive(Debug, Clone)]
pub struct FvData {
    /// The data folder (photos and their cameras).
    pub data: PathBuf,
    /// How it is loaded (masks, silhouettes, scale, photo fit, scoring silhouettes).
    pub options: DataOptions,
    /// How the model is built (unless `model_file` is given).
    pub model: ModelParams,
    /// `vt fv hull`'s model file to use instead of building one.
    pub model_file: Option<PathBuf>,
}

impl FvData {
    /// The run's inputs, which no output may replace: the data folder, the masks folder, the
    /// model file.
    pub fn inputs(&self) -> Vec<&Path> {
        [
            Some(self.data.as_path()),
            self.options.masks.as_deref(),
            self.model_file.as_deref(),
        ]
        .into_iter()
        .flatten()
        .collect()
    }

    /// Checks the options (before anything is read).
    pub fn check(&self) -> Result<()> {
        self.model.check()?;
        self.options.check()?;
        if let Some(d) = self.options.masks.as_ref().filter(|d| !d.is_dir()) {
            return Err(Error::Param {
                name: "masks",
                value: d.display().to_string(),
                why: "not a folder".into(),
            });
        }
        Ok(())
    }

    /// Loads the data folder; its notes (e.g. photos rescaled) go to `progress` as they come.
    pub fn load(&self, progress: &mut dyn Progress) -> Result<Dataset> {
        let d = Dataset::load(&self.data, &self.options)?;
        for n in &d.notes {
            progress.note(n);
        }
        Ok(d)
    }
}

/// The model from all views, or all but `withheld`, with progress per stage.
fn build(
    d: &Dataset,
    withheld: Option<usize>,
    m: &ModelParams,
    progress: &mut dyn Progress,
) -> Result<(VoxelModel, BuildSummary)> {
    let mut stage = String::new();
    let r = d.build_without(withheld, m, &mut |s, i, n| {
        if s != stage {
            progress.finish();
            progress.start(s, Some(n));
            stage = s.to_string();
        }
        progress.at(i, None);
    });
    progress.finish();
    r.map_err(|e| Error::In {
        what: d
            .cameras_file
            .parent()
            .unwrap_or(&d.cameras_file)
            .display()
            .to_string(),
        cause: Box::new(e.into()),
    })
}

/// The share of a model's surface seen by no camera, in words.
pub fn unseen_words(model: &VoxelModel) -> String {
    let unseen = model.surface.iter().filter(|v| v.seen_by == 0).count();
    format!(
        "{:.1} % seen by no camera",
        100.0 * unseen as f64 / model.surface.len().max(1) as f64
    )
}

/// The spacing of the model's depth maps, in words, after a comma (empty without maps): every
/// pixel when the fine iterations ran, else every `pixel_step` pixels.
pub fn depth_words(model: &VoxelModel) -> String {
    model.depths.first().map_or(String::new(), |m| {
        format!(", {}", vt_fv::dataset::depth_spacing(m.step))
    })
}

/// The model a view is made from: built here from every view, or read from a model file (checked
/// against the data folder), with one line saying which and how long it took.
pub struct ModelUsed {
    /// The model.
    pub model: VoxelModel,
    /// The model file's header, when read from one.
    pub header: Option<ModelHeader>,
    /// Where it came from, in words.
    pub line: String,
}

fn model_for(data: &FvData, d: &Dataset, progress: &mut dyn Progress) -> Result<ModelUsed> {
    let Some(f) = &data.model_file else {
        let (model, s) = build(d, None, &data.model, progress)?;
        let line = format!(
            "model: built, {} surface voxels ({} passes, {}{}) in {:.2} s",
            s.surface_voxels,
            s.photo_hull_passes,
            unseen_words(&model),
            depth_words(&model),
            s.visual_hull_secs + s.photo_hull_secs
        );
        return Ok(ModelUsed {
            model,
            header: None,
            line,
        });
    };
    read_used(f, d)
}

/// The model in `vt fv hull`'s file `f`, checked against the data folder, with its line.
fn read_used(f: &Path, d: &Dataset) -> Result<ModelUsed> {
    let t = Instant::now();
    let (model, h) = read_model(f, d)?;
    let line = format!(
        "model: read from {} in {:.2} s ({} surface voxels, {}{}; building it took {:.2} s)",
        f.display(),
        t.elapsed().as_secs_f64(),
        model.surface.len(),
        unseen_words(&model),
        depth_words(&model),
        h.build_secs
    );
    Ok(ModelUsed {
        model,
        header: Some(h),
        line,
    })
}

/// Refuses a model built without a view where every view is needed (render, orbit).
fn whole(used: &ModelUsed, data: &FvData) -> Result<()> {
    if let (Some(k), Some(f)) = (
        used.header.as_ref().and_then(|h| h.withheld),
        &data.model_file,
    ) {
        return Err(Error::Param {
            name: "model",
            value: f.display().to_string(),
            why: format!("built without view {k} (for `vt fv eval --leave-out {k}`); render and orbit take a model of every view"),
        });
    }
    Ok(())
}

/// `vt fv hull`'s job: the model of every view (or all but `leave_out`) into the folder `out`.
#[derive(Debug, Clone)]
pub struct HullJob {
    /// The data and the model's settings (`model_file` is not used).
    pub data: FvData,
    /// Build without this view (for a leave-one-out with `--model`).
    pub leave_out: Option<usize>,
    /// The output folder: model.vtfv, hull.ply, summary.json.
    pub out: PathBuf,
}

/// What [`hull`] built.
pub struct HullDone {
    /// The data folder as loaded.
    pub dataset: Dataset,
    /// The build's figures.
    pub summary: BuildSummary,
    /// Each silhouette against the hull of the others (3 views or more).
    pub check: Option<SilhouetteCheck>,
}

/// Builds the model and writes it (atomic: the folder appears only when complete).
pub fn hull(job: &HullJob, progress: &mut dyn Progress) -> Result<HullDone> {
    job.data.check()?;
    // The output is checked before any work: never the data folder, never a foreign path.
    let dir = Output::dir(&job.out, OutputKind::Hull, &job.data.inputs())?;
    let d = job.data.load(progress)?;
    if let Some(k) = job.leave_out {
        d.check_withheld(&[k])?;
    }
    let m = &job.data.model;
    let (model, s) = build(&d, job.leave_out, m, progress)?;
    let bounds = Aabb::new(s.bounds_min.into(), s.bounds_max.into());
    // Fewer than 3 views leave nothing to check against.
    let check = if d.cams.len() >= 3 {
        Some(d.check_silhouettes(bounds).map_err(|e| Error::In {
            what: "silhouette check".into(),
            cause: Box::new(e.into()),
        })?)
    } else {
        None
    };
    let header = d.model_header(job.leave_out, m, &s);
    write_hull(dir.path(), &d, &model, &header, &s, check.as_ref())?;
    dir.commit()?;
    Ok(HullDone {
        dataset: d,
        summary: s,
        check,
    })
}

/// Checks that `out` names a file of one of `exts` (lower case), else says which to use.
fn check_extension(out: &Path, exts: &[&str]) -> Result<()> {
    let ext = out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if ext.as_deref().is_some_and(|e| exts.contains(&e)) {
        return Ok(());
    }
    let names: Vec<String> = exts.iter().map(|e| format!(".{e}")).collect();
    Err(Error::Param {
        name: "out",
        value: out.display().to_string(),
        why: format!("use a {} file name", names.join(" or ")),
    })
}

/// `vt fv render`'s job: one new view into an image file.
#[derive(Debug, Clone)]
pub struct FvRenderJob {
    /// The data and the model.
    pub data: FvData,
    /// How the view is made.
    pub view: ViewOptions,
    /// The new camera: a par line, `angle:DEG` or `between:I,J,T` (`Dataset::camera`).
    pub camera: String,
    /// The output image (.png or .jpg).
    pub out: PathBuf,
}

/// What [`render`] made.
pub struct FvRendered {
    /// Where the model came from.
    pub model_line: String,
    /// Seconds of the view itself.
    pub view_secs: f64,
    /// What the method did, in words.
    pub what: String,
    /// The image size.
    pub size: (u32, u32),
}

/// Renders one new view and writes it.
pub fn render(job: &FvRenderJob, progress: &mut dyn Progress) -> Result<FvRendered> {
    job.data.check()?;
    check_extension(&job.out, &["png", "jpg", "jpeg"])?;
    let inputs = job.data.inputs();
    // Checked before any work (nothing is created yet).
    drop(Output::file(&job.out, OutputKind::Image, &inputs)?);
    let d = job.data.load(progress)?;
    let (w, h) = d.size();
    let view = job.view.params(w, h)?;
    let camera = |target: nalgebra::Vector3<f64>, bounds: &Aabb| {
        d.camera(&job.camera, job.data.options.scale, &target, bounds)
            .map_err(|e| Error::Field {
                name: "camera",
                cause: Box::new(e.into()),
            })
    };
    let used = if job.data.model_file.is_some() {
        let used = model_for(&job.data, &d, progress)?;
        whole(&used, &job.data)?;
        used
    } else {
        // Check the camera against the volume before the expensive model build.
        let bounds = d.volume(job.data.model.bounds).map_err(|e| Error::In {
            what: "volume bounds from the silhouettes".into(),
            cause: Box::new(e.into()),
        })?;
        camera(bounds.centre(), &bounds)?;
        model_for(&job.data, &d, progress)?
    };
    // Ring cameras look at the model's centre.
    let cam = camera(model_centre(&used.model), &used.model.grid.bounds())?;
    let t = Instant::now();
    progress.start(view.name(), Some(1));
    // What eval scores: the model's render trimmed to the reference silhouettes, then the
    // method's image.
    let v = novel_view_in(
        &used.model,
        &d.cams,
        &d.images,
        Some(&d.masks),
        &cam,
        w,
        h,
        &view,
    )
    .map_err(|e| Error::Field {
        name: "method",
        cause: Box::new(Error::In {
            what: view.name().into(),
            cause: Box::new(e.into()),
        }),
    })?;
    progress.finish();
    let what = v.describe(&d.cams, &view);
    if v.rough.coverage.count_ones() == 0 {
        return Err(Error::Param {
            name: "camera",
            value: cam.name.clone(),
            why: "camera sees none of the model".into(),
        });
    }
    let view_secs = t.elapsed().as_secs_f64();
    let png = job
        .out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        == Some("png".into());
    match d.background {
        Some(bg) => {
            let img = vt_fv::composite::onto(&v.guided, &v.rough.coverage, bg);
            vt_io::writer::write_image(&job.out, &inputs, &img)?
        }
        None if png => {
            let img = vt_fv::composite::with_alpha(&v.guided, &v.rough.coverage);
            vt_io::writer::write_image(&job.out, &inputs, &img)?
        }
        None => vt_io::writer::write_image(&job.out, &inputs, &v.guided)?,
    };
    Ok(FvRendered {
        model_line: used.line,
        view_secs,
        what,
        size: (w, h),
    })
}

/// Most frames of one orbit.
pub const MAX_ORBIT_FRAMES: usize = 10_000;
/// Highest orbit frame rate.
pub const MAX_ORBIT_FPS: u32 = 240;

/// `vt fv orbit`'s job: views around the cameras' ring into an mp4 or GIF.
#[derive(Debug, Clone)]
pub struct OrbitJob {
    /// The data and the model.
    pub data: FvData,
    /// How each view is made.
    pub view: ViewOptions,
    /// Frames in one turn, 1..=[`MAX_ORBIT_FRAMES`].
    pub frames: usize,
    /// Frames per second, 1..=[`MAX_ORBIT_FPS`].
    pub fps: u32,
    /// The output (.mp4, .gif or .apng).
    pub out: PathBuf,
}

impl OrbitJob {
    /// Checks the frame count, frame rate and output name.
    pub fn check(&self) -> Result<()> {
        self.data.check()?;
        check_extension(&self.out, &vt_io::writer::VIDEO_EXTENSIONS)?;
        if self.frames == 0 || self.frames > MAX_ORBIT_FRAMES {
            return Err(Error::Param {
                name: "frames",
                value: self.frames.to_string(),
                why: format!("must be in 1..={MAX_ORBIT_FRAMES}"),
            });
        }
        if self.fps == 0 || self.fps > MAX_ORBIT_FPS {
            return Err(Error::Param {
                name: "fps",
                value: self.fps.to_string(),
                why: format!("must be in 1..={MAX_ORBIT_FPS}"),
            });
        }
        Ok(())
    }
}

/// What [`orbit`] made.
pub struct Orbited {
    /// Where the model came from.
    pub model_line: String,
    /// Seconds of the frames (model excluded).
    pub secs: f64,
    /// The frame size.
    pub size: (u32, u32),
    /// Steps between consecutive frames (the orbit's steadiness).
    pub steadiness: Steadiness,
    /// How each frame was made, in words.
    pub describe: String,
}

/// Renders the orbit from one model and encodes it (vt-io's video writer: atomic, marked).
pub fn orbit(job: &OrbitJob, progress: &mut dyn Progress) -> Result<Orbited> {
    job.check()?;
    let inputs = job.data.inputs();
    // Checked before any work (nothing is created yet).
    drop(Output::file(&job.out, OutputKind::Video, &inputs)?);
    let d = job.data.load(progress)?;
    let (w, h) = d.size();
    let view = job.view.params(w, h)?;
    let ring = Ring::fit(&d.cams).map_err(|e| Error::In {
        what: "orbit: the cameras' ring".into(),
        cause: Box::new(e.into()),
    })?;
    // One model for every frame.
    let used = model_for(&job.data, &d, progress)?;
    whole(&used, &job.data)?;
    let target = model_centre(&used.model);
    let mut video = vt_io::writer::VideoWriter::create(&job.out, &inputs, w, h, job.fps as f64)?;
    progress.start("orbit frames", Some(job.frames as u64));
    let t = Instant::now();
    let steadiness = vt_fv::orbit::orbit::<Error>(
        &used.model,
        &d.cams,
        &d.images,
        Some(&d.masks),
        &ring,
        &target,
        job.frames,
        (w, h),
        &view,
        &mut |i, angle, v| {
            let frame = vt_fv::composite::placed(&v.guided, &v.rough.coverage, d.background);
            video.write(&frame).map_err(|e| Error::In {
                what: format!("frame {i} (angle {angle:.1})"),
                cause: Box::new(e.into()),
            })?;
            progress.at(i as u64 + 1, None);
            Ok(())
        },
    )?;
    let secs = t.elapsed().as_secs_f64();
    progress.finish();
    video.finish()?;
    Ok(Orbited {
        model_line: used.line,
        secs,
        size: (w, h),
        steadiness,
        describe: view.describe(),
    })
}

/// `vt fv eval`'s job: views withheld one at a time, made without them, and scored.
#[derive(Debug, Clone)]
pub struct EvalJob {
    /// The data and the model (a model file must have been built without the one withheld view).
    pub data: FvData,
    /// How each view is made.
    pub view: ViewOptions,
    /// The views to withhold, 0-based (empty with `test`).
    pub leave_out: Vec<usize>,
    /// A test set instead of withheld views: a NeRF transforms file (as given, else inside the
    /// data folder) or a data folder; every view of it is made from the model of every view.
    pub test: Option<PathBuf>,
    /// A folder for each view's images and eval.json.
    pub save: Option<PathBuf>,
}

/// `--save DIR`: a fresh output folder (or one replacing a previous vt output), refused when
/// DIR is a file.
fn save_folder(save: Option<&Path>, inputs: &[&Path]) -> Result<Option<Output>> {
    match save {
        Some(dir) if dir.exists() && !dir.is_dir() => Err(Error::Param {
            name: "save",
            value: dir.display().to_string(),
            why: "exists and is not a folder".into(),
        }),
        Some(dir) => Ok(Some(Output::dir(dir, OutputKind::Folder, inputs)?)),
        None => Ok(None),
    }
}

/// What [`eval`] measured against a test set.
pub struct TestEvaluated {
    /// The training data as loaded.
    pub dataset: Dataset,
    /// The test set's file or folder, as found.
    pub test: PathBuf,
    /// The scores.
    pub summary: TestSummary,
    /// Where the model came from.
    pub model_line: String,
    /// How each view was made, in words.
    pub describe: String,
}

/// The test set's path: as given when it exists, else inside the data folder.
fn test_path(given: &Path, data: &Path) -> Result<PathBuf> {
    if given.exists() {
        return Ok(given.to_path_buf());
    }
    let inside = data.join(given);
    if given.is_relative() && inside.exists() {
        return Ok(inside);
    }
    Err(Error::Param {
        name: "test",
        value: given.display().to_string(),
        why: format!("no such file or folder (nor in {})", data.display()),
    })
}

/// Number of views the contact sheet shows (the worst by whole-image PSNR).
pub const CONTACT_VIEWS: usize = 4;

/// Builds the model from every (chosen) view and scores each view of the test set; saves every
/// view and a contact sheet of the worst when asked.
pub fn eval_test(job: &EvalJob, progress: &mut dyn Progress) -> Result<TestEvaluated> {
    job.data.check()?;
    let given = job.test.as_ref().expect("eval_test is for a test set");
    if !job.leave_out.is_empty() {
        return Err(Error::Param {
            name: "leave-out",
            value: format!("{:?}", job.leave_out),
            why: "scores either withheld views or a test set (--test), not both".into(),
        });
    }
    let test_at = test_path(given, &job.data.data)?;
    let mut inputs = job.data.inputs();
    inputs.push(test_at.as_path());
    let save = save_folder(job.save.as_deref(), &inputs)?;
    let d = job.data.load(progress)?;
    // The test photos over the same background as the training photos (and the views).
    let mut opt = job.data.options.clone();
    opt.views.clear();
    opt.background = match d.background {
        Some(c) => Background::Colour(c),
        None => Background::Transparent,
    };
    let test = Dataset::load_set(&test_at, &opt).map_err(|e| Error::Field {
        name: "test",
        cause: Box::new(e.into()),
    })?;
    let (w, h) = d.size();
    let view = job.view.params(w, h)?;
    let t = Instant::now();
    let used = model_for(&job.data, &d, progress)?;
    whole(&used, &job.data)?;
    let model_secs = match &used.header {
        Some(h) => h.build_secs,
        None => t.elapsed().as_secs_f64(),
    };
    progress.start("test views", Some(test.cams.len() as u64));
    let (views, images) = d
        .score_test_set(&used.model, &test, &view, &mut |i| {
            progress.at(i as u64 + 1, None)
        })
        .map_err(|e| Error::In {
            what: format!("test set {}", test_at.display()),
            cause: Box::new(e.into()),
        })?;
    progress.finish();
    let summary = TestSummary::new(view.name(), d.background, d.cams.len(), model_secs, views);
    if let Some(dir) = save {
        write_test_outputs(dir.path(), &summary, &images, CONTACT_VIEWS)?;
        dir.commit()?;
    }
    Ok(TestEvaluated {
        dataset: d,
        test: test_at,
        summary,
        model_line: used.line,
        describe: view.describe(),
    })
}

/// What [`eval`] measured.
pub struct Evaluated {
    /// The data folder as loaded (camera names for the reports).
    pub dataset: Dataset,
    /// One report per withheld view.
    pub reports: Vec<EvalReport>,
    /// Their summary (means, JSON).
    pub summary: EvalSummary,
    /// Where the model came from when read from a file.
    pub model_line: Option<String>,
    /// How each view was made, in words.
    pub describe: String,
}

/// Withholds each view in turn, makes it, scores it and the baselines; saves images when asked.
pub fn eval(job: &EvalJob, progress: &mut dyn Progress) -> Result<Evaluated> {
    job.data.check()?;
    let inputs = job.data.inputs();
    let save = save_folder(job.save.as_deref(), &inputs)?;
    if job.data.model_file.is_some() && job.leave_out.len() != 1 {
        return Err(Error::Param {
            name: "model",
            value: String::new(),
            why: "a model is built without one view; give that one view to --leave-out".into(),
        });
    }
    let d = job.data.load(progress)?;
    d.check_withheld(&job.leave_out)?;
    let (w, h) = d.size();
    let view = job.view.params(w, h)?;
    let read = match &job.data.model_file {
        Some(f) => Some((f, read_used(f, &d)?)),
        None => None,
    };
    progress.start("leave one out", Some(job.leave_out.len() as u64));
    let mut reports = Vec::new();
    for (i, &k) in job.leave_out.iter().enumerate() {
        let (r, imgs) = match &read {
            Some((f, used)) => {
                let header = used.header.as_ref().expect("read from a file");
                d.leave_one_out_with(k, &used.model, header, f, &view)?
            }
            None => d
                .leave_one_out(k, &job.data.model, &view)
                .map_err(|e| Error::In {
                    what: format!("leaving out view {k} ({})", d.cams[k].name),
                    cause: Box::new(e.into()),
                })?,
        };
        if let Some(dir) = &save {
            let sub = dir.path().join(format!("view_{k:02}"));
            std::fs::create_dir(&sub).map_err(|e| vt_io::Error::io(&sub, e))?;
            write_eval_images(&sub, &imgs, &d.score_masks[k])?;
        }
        reports.push(r);
        progress.at(i as u64 + 1, None);
    }
    progress.finish();
    let summary = EvalSummary::new(view.name(), &reports, &d.cams);
    if let Some(dir) = save {
        write_json(&dir.path().join("eval.json"), &summary.views)?;
        dir.commit()?;
    }
    Ok(Evaluated {
        dataset: d,
        reports,
        summary,
        model_line: read.map(|(_, used)| used.line),
        describe: view.describe(),
    })
}

/// Preset views of a page: this many around the cameras' ring (`angle:DEG`, evenly spaced
/// from the first camera).
pub const PAGE_VIEWS: usize = 8;

/// `vt fv export`'s job: the model and the photos as a page that renders new views live.
#[derive(Debug, Clone)]
pub struct FvExportJob {
    /// The data and the model.
    pub data: FvData,
    /// How the page textures its views (the references; the rest as `vt fv render`'s default).
    pub view: ViewOptions,
    /// The output folder (index.html and data/); must not exist.
    pub out: PathBuf,
}

/// What [`fv_export`] wrote.
pub struct FvExported {
    /// Where the model came from.
    pub model_line: String,
    /// The page's files and bytes.
    pub summary: vt_web::fv::FvSummary,
    /// The preset views' camera specs (`vt fv render --camera`'s spelling), in order.
    pub views: Vec<String>,
}

/// The page's parts: the data loaded, the view settings (checked before the model is built),
/// the model, the preset views and their specs.
struct PageParts {
    d: Dataset,
    params: vt_fv::pipeline::ViewParams,
    used: ModelUsed,
    views: Vec<vt_fv::camera::Camera>,
    specs: Vec<String>,
}

fn page_parts(data: &FvData, view: &ViewOptions, progress: &mut dyn Progress) -> Result<PageParts> {
    data.check()?;
    let d = data.load(progress)?;
    let (w, h) = d.size();
    let params = view.params(w, h)?;
    let used = model_for(data, &d, progress)?;
    whole(&used, data)?;
    let centre = model_centre(&used.model);
    let bounds = used.model.grid.bounds();
    let specs: Vec<String> = (0..PAGE_VIEWS)
        .map(|i| format!("angle:{}", 360.0 * i as f64 / PAGE_VIEWS as f64))
        .collect();
    let views = specs
        .iter()
        .map(|s| {
            d.camera(s, data.options.scale, &centre, &bounds)
                .map_err(|e| Error::Field {
                    name: "camera",
                    cause: Box::new(e.into()),
                })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(PageParts {
        d,
        params,
        used,
        views,
        specs,
    })
}

impl PageParts {
    /// The page's description of these parts.
    fn model<'a>(&'a self, title: &'a str) -> vt_web::fv::FvModel<'a> {
        vt_web::fv::FvModel {
            cams: &self.d.cams,
            images: &self.d.images,
            model: &self.used.model,
            views: &self.views,
            background: self.d.background,
            masks: &self.d.masks,
            clip: self.params.clip.as_ref(),
            depth_clip: self.params.depth_clip.as_ref(),
            texture: &self.params.texture,
            title,
        }
    }
}

/// Writes the page for the data folder's model into `job.out`.
pub fn fv_export(job: &FvExportJob, progress: &mut dyn Progress) -> Result<FvExported> {
    let inputs = job.data.inputs();
    // Checked before any work (nothing is created yet).
    drop(Output::dir(&job.out, OutputKind::WebExport, &inputs)?);
    let parts = page_parts(&job.data, &job.view, progress)?;
    let title = crate::export::title(&job.data.data);
    progress.start("page", None);
    let summary = vt_web::fv::fv_export(&parts.model(&title), &job.out, &inputs)?;
    progress.finish();
    Ok(FvExported {
        model_line: parts.used.line,
        summary,
        views: parts.specs,
    })
}

/// The page for the data folder's model in memory (`vt fv view`), with the model's line.
pub fn fv_page(
    data: &FvData,
    view: &ViewOptions,
    progress: &mut dyn Progress,
) -> Result<(std::collections::BTreeMap<String, Vec<u8>>, String)> {
    let parts = page_parts(data, view, progress)?;
    let title = crate::export::title(&data.data);
    let (files, _) = vt_web::fv::fv_page(&parts.model(&title))?;
    Ok((files, parts.used.line))
}
