//! What the System B use cases write and print: the hull folder, the silhouette check, the
//! evaluation images and summaries.

use super::*;

/// Grid of the visual hulls [`Dataset::check_silhouettes`] carves (64 voxels along the longest
/// side: a tenth of a second per view on the kettle).
pub const CHECK_GRID: usize = 64;

/// The silhouettes' cross-view consistency ([`crate::hull::silhouette_agreement`]).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SilhouetteCheck {
    /// IoU below which a view is named.
    pub threshold: f64,
    /// Each view's photo name and IoU against the hull of the others, in camera order.
    pub views: Vec<(String, f64)>,
    /// The views that disagree: (index, photo name, IoU).
    pub disagreeing: Vec<(usize, String, f64)>,
    /// Views whose silhouette covers more than [`FULL_SHARE`] of the photo (index, photo name,
    /// share): no segmentation at all, which agrees with anything (e.g. the dark-backdrop
    /// threshold on a light backdrop).
    pub full: Vec<(usize, String, f64)>,
}

/// Share of a photo above which [`SilhouetteCheck`] names a silhouette as covering all of it
/// (0.9).
pub const FULL_SHARE: f64 = 0.9;

/// One line: the IoU range, and the photos that disagree by name.
impl std::fmt::Display for SilhouetteCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let iou: Vec<f64> = self.views.iter().map(|v| v.1).collect();
        let lo = iou.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = iou.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        write!(
            f,
            "silhouette check: IoU of each view's silhouette against the hull of the others {lo:.2}-{hi:.2}; "
        )?;
        if !self.full.is_empty() {
            let names: Vec<String> = self
                .full
                .iter()
                .map(|(i, n, v)| format!("view {i} ({n}): {:.0}%", v * 100.0))
                .collect();
            write!(
                f,
                "{} cover nearly the whole photo (not segmented: a light backdrop thresholded as dark? try --silhouettes backdrop): {}; ",
                names.len(),
                names.join(", ")
            )?;
        }
        if self.disagreeing.is_empty() {
            return write!(f, "all {} agree (>= {})", self.views.len(), self.threshold);
        }
        let names: Vec<String> = self
            .disagreeing
            .iter()
            .map(|(i, n, v)| format!("view {i} ({n}): {v:.2}"))
            .collect();
        write!(
            f,
            "{} below {} disagree with the others (a wrong silhouette or camera; give masks with --masks or drop the photo): {}",
            names.len(),
            self.threshold,
            names.join(", ")
        )
    }
}

/// Writes `hull.ply` (the coloured surface voxels), `summary.json` and the model file
/// [`MODEL_FILE`] (what `render`, `orbit` and `eval` read with `--model`) into `dir`.
pub fn write_hull(
    dir: &Path,
    d: &Dataset,
    model: &VoxelModel,
    header: &ModelHeader,
    build: &BuildSummary,
    check: Option<&SilhouetteCheck>,
) -> Result<(), DataError> {
    write_model(&dir.join(MODEL_FILE), model, header)?;
    let photo_threshold = header.photo_threshold;
    let ply = dir.join("hull.ply");
    let mut bytes = Vec::new();
    model
        .to_ply(&mut bytes)
        .map_err(|e| path_err(&ply, e.to_string()))?;
    std::fs::write(&ply, bytes).map_err(|e| path_err(&ply, e.to_string()))?;
    let (w, h) = d.size();
    let summary = HullSummary {
        format: "vt-fv-hull",
        version: 1,
        cameras: d.cameras_file.display().to_string(),
        views: d.cams.len(),
        image_size: [w, h],
        silhouettes: d.silhouettes.clone(),
        photo_threshold,
        build: build.clone(),
        silhouette_check: check.cloned(),
    };
    write_json(&dir.join("summary.json"), &summary)
}

/// Writes `value` as pretty JSON to `path`.
pub fn write_json(path: &Path, value: &impl Serialize) -> Result<(), DataError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| path_err(path, e.to_string()))?;
    std::fs::write(path, text).map_err(|e| path_err(path, e.to_string()))
}

/// Writes one withheld view's images into `dir` (which must exist): `truth`, `nearest_photo`,
/// `rough`, `rough_blur2`, `guide`, `guided` and the error maps of `rough`, `rough_blur2` and
/// `guided` against the truth (`*_error.png`), and the scoring `silhouette.png`.
pub fn write_eval_images(dir: &Path, imgs: &EvalImages, mask: &Mask) -> Result<(), DataError> {
    let err = |img: &RgbImage| error_map(img, &imgs.truth, mask);
    let files = [
        ("truth.png", &imgs.truth),
        ("nearest_photo.png", &imgs.nearest_photo),
        ("rough.png", &imgs.rough),
        ("rough_blur2.png", &imgs.rough_blur2),
        ("guide.png", &imgs.guide),
        ("guided.png", &imgs.guided),
        ("rough_error.png", &err(&imgs.rough)),
        ("rough_blur2_error.png", &err(&imgs.rough_blur2)),
        ("guided_error.png", &err(&imgs.guided)),
    ];
    for (name, img) in files {
        let p = dir.join(name);
        img.save(&p).map_err(|e| path_err(&p, e.to_string()))?;
    }
    let p = dir.join("silhouette.png");
    crate::silhouette::mask_image(mask)
        .save(&p)
        .map_err(|e| path_err(&p, e.to_string()))
}

/// One withheld view in `vt fv eval`'s JSON: scores inside the withheld silhouette (and `whole`,
/// over the whole image), the model's silhouette IoU, and seconds per stage.
#[derive(Debug, Serialize)]
pub struct ViewSummary {
    /// The withheld view (0-based).
    pub withheld: usize,
    /// Its image name.
    pub name: String,
    /// The nearest reference photo.
    pub reference: usize,
    /// The rough render.
    pub rough: Score,
    /// The rough render blurred (sigma 2).
    pub rough_blur2: Score,
    /// The nearest photo as it is.
    pub nearest_photo: Score,
    /// The guide.
    pub guide: Score,
    /// The result.
    pub guided: Score,
    /// The same five over the whole image.
    pub whole: BTreeMap<&'static str, Score>,
    /// IoU of the rough render's coverage against the withheld silhouette.
    pub silhouette_iou: f64,
    /// Surface voxels of the model.
    pub surface_voxels: usize,
    /// Seconds per stage.
    pub secs: BTreeMap<&'static str, f64>,
    /// Seconds in all.
    pub total_secs: f64,
}

impl ViewSummary {
    /// The summary of a report; `name` is the withheld view's image name.
    pub fn new(r: &EvalReport, name: &str) -> Self {
        Self {
            withheld: r.withheld,
            name: name.to_string(),
            reference: r.reference,
            rough: r.rough.inside,
            rough_blur2: r.rough_blur2.inside,
            nearest_photo: r.nearest_photo.inside,
            guide: r.guide.inside,
            guided: r.guided.inside,
            whole: r.candidates().iter().map(|(n, s)| (*n, s.whole)).collect(),
            silhouette_iou: r.silhouette_iou,
            surface_voxels: r.surface_voxels,
            secs: r.times.iter().copied().collect(),
            total_secs: r.total_secs(),
        }
    }
}

/// `vt fv eval --json`: means over the withheld views inside their silhouettes, and every view.
#[derive(Debug, Serialize)]
pub struct EvalSummary {
    /// [`ViewParams::name`].
    pub method: &'static str,
    /// Mean of the rough render's scores.
    pub rough: Score,
    /// ... of the blurred rough render.
    pub rough_blur2: Score,
    /// ... of the nearest photo.
    pub nearest_photo: Score,
    /// ... of the guide.
    pub guide: Score,
    /// ... of the result.
    pub guided: Score,
    /// Mean silhouette IoU.
    pub silhouette_iou: f64,
    /// Every view.
    pub views: Vec<ViewSummary>,
}

impl EvalSummary {
    /// Means over `reports` (at least one), the views named from `cams`.
    pub fn new(method: &'static str, reports: &[EvalReport], cams: &[Camera]) -> Self {
        let mean = |k: usize| mean_score(reports, k);
        Self {
            method,
            nearest_photo: mean(0),
            rough: mean(1),
            rough_blur2: mean(2),
            guide: mean(3),
            guided: mean(4),
            silhouette_iou: reports.iter().map(|r| r.silhouette_iou).sum::<f64>()
                / reports.len().max(1) as f64,
            views: reports
                .iter()
                .map(|r| ViewSummary::new(r, &cams[r.withheld].name))
                .collect(),
        }
    }
}

/// The means table: PSNR and SSIM of each candidate, and the silhouette IoU.
impl std::fmt::Display for EvalSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let n = self.views.len();
        writeln!(
            f,
            "mean over {n} views, inside the silhouettes: PSNR dB / SSIM"
        )?;
        for (name, s) in [
            ("nearest_photo", self.nearest_photo),
            ("rough", self.rough),
            ("rough_blur2", self.rough_blur2),
            ("guide", self.guide),
            ("guided", self.guided),
        ] {
            writeln!(f, "{name:<14} {:>10.2} {:>8.3}", s.psnr, s.ssim)?;
        }
        write!(f, "silhouette IoU {:.3}", self.silhouette_iou)
    }
}

/// Mean inside-silhouette score of candidate `k` ([`EvalReport::candidates`] order) over
/// `reports`.
pub fn mean_score(reports: &[EvalReport], k: usize) -> Score {
    let n = reports.len().max(1) as f64;
    let s = |f: &dyn Fn(Score) -> f64| {
        reports
            .iter()
            .map(|r| f(r.candidates()[k].1.inside))
            .sum::<f64>()
            / n
    };
    Score {
        psnr: s(&|x| x.psnr),
        ssim: s(&|x| x.ssim),
    }
}
