//! Scoring against a test set: every view of a second camera set (a NeRF `transforms_test.json`,
//! or another data folder) made from the model and scored as the NeRF benchmarks score it, on
//! the whole image over the data's background, and inside the test photo's silhouette.

use super::*;
use crate::composite::placed;
use crate::eval::psnr;
use crate::pipeline::novel_view_in;
use crate::texture::{model_centre, nearest_by_direction};

/// PSNR and SSIM ([`vt_core::metrics::ssim_rgb`], the benchmarks' RGB SSIM) of one image.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RgbScore {
    /// PSNR in dB over RGB.
    pub psnr: f64,
    /// Mean SSIM of the three channels.
    pub ssim: f64,
}

fn rgb_score(img: &RgbImage, truth: &RgbImage, mask: Option<&Mask>) -> crate::Result<RgbScore> {
    Ok(RgbScore {
        psnr: psnr(img, truth, mask)?,
        ssim: vt_core::metrics::ssim_rgb(img, truth, mask)?,
    })
}

/// One test view, made and scored.
#[derive(Debug, Clone, Serialize)]
pub struct TestView {
    /// The test photo's name.
    pub name: String,
    /// The whole image over the background (the benchmarks' figure).
    pub whole: RgbScore,
    /// Inside the test photo's silhouette.
    pub inside: RgbScore,
    /// The rough render (the voxel model's colours) on the whole image, the baseline.
    pub rough: RgbScore,
    /// The nearest training photo as it is, on the whole image.
    pub nearest_photo: RgbScore,
    /// IoU of the view's coverage against the test photo's silhouette.
    pub coverage_iou: f64,
    /// The training photos the view was made from, nearest first.
    pub references: Vec<String>,
    /// Seconds to make the view (scoring excluded).
    pub secs: f64,
}

/// A test view's images, for the contact sheet (which adds the error map) and `--save`.
pub struct TestImages {
    /// The test photo (over the background).
    pub truth: RgbImage,
    /// The new view (over the background).
    pub view: RgbImage,
}

/// Means over the test views.
#[derive(Debug, Clone, Serialize)]
pub struct TestSummary {
    /// How the views were made (the method's name).
    pub method: String,
    /// The background the whole images are scored over (`None`: black, no background).
    pub background: Option<[u8; 3]>,
    /// Training views the model was built from.
    pub train_views: usize,
    /// Mean over the views: whole image.
    pub whole: RgbScore,
    /// Mean over the views: inside the silhouette.
    pub inside: RgbScore,
    /// Mean over the views: the rough render.
    pub rough: RgbScore,
    /// Mean over the views: the nearest training photo.
    pub nearest_photo: RgbScore,
    /// Mean coverage IoU, and the worst view's.
    pub coverage_iou: f64,
    /// The worst view's coverage IoU.
    pub coverage_iou_worst: f64,
    /// Seconds to build the model (0 when read from a file).
    pub model_secs: f64,
    /// Median seconds per view.
    pub view_secs_median: f64,
    /// Every view.
    pub views: Vec<TestView>,
}

fn mean_score(v: &[RgbScore]) -> RgbScore {
    let n = v.len().max(1) as f64;
    RgbScore {
        psnr: v.iter().map(|s| s.psnr).sum::<f64>() / n,
        ssim: v.iter().map(|s| s.ssim).sum::<f64>() / n,
    }
}

impl TestSummary {
    /// Means over `views`.
    pub fn new(
        method: &str,
        background: Option<[u8; 3]>,
        train_views: usize,
        model_secs: f64,
        views: Vec<TestView>,
    ) -> Self {
        let pick =
            |f: fn(&TestView) -> RgbScore| mean_score(&views.iter().map(f).collect::<Vec<_>>());
        let mut secs: Vec<f64> = views.iter().map(|v| v.secs).collect();
        secs.sort_by(f64::total_cmp);
        let n = views.len().max(1) as f64;
        Self {
            method: method.to_string(),
            background,
            train_views,
            whole: pick(|v| v.whole),
            inside: pick(|v| v.inside),
            rough: pick(|v| v.rough),
            nearest_photo: pick(|v| v.nearest_photo),
            coverage_iou: views.iter().map(|v| v.coverage_iou).sum::<f64>() / n,
            coverage_iou_worst: views
                .iter()
                .map(|v| v.coverage_iou)
                .fold(f64::INFINITY, f64::min),
            model_secs,
            view_secs_median: secs.get(secs.len() / 2).copied().unwrap_or(0.0),
            views,
        }
    }

    /// The views' indices, worst whole-image PSNR first.
    pub fn worst_first(&self) -> Vec<usize> {
        let mut order: Vec<usize> = (0..self.views.len()).collect();
        order.sort_by(|&a, &b| {
            self.views[a]
                .whole
                .psnr
                .total_cmp(&self.views[b].whole.psnr)
        });
        order
    }
}

/// The benchmark row and what stands behind it, a few lines.
impl std::fmt::Display for TestSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let bg = match self.background {
            Some([255, 255, 255]) => "white".to_string(),
            Some(c) => format!("rgb({},{},{})", c[0], c[1], c[2]),
            None => "black (no background)".to_string(),
        };
        writeln!(
            f,
            "{} test views from {} training views, method {}: whole image over {bg}: PSNR {:.2} dB, SSIM {:.3}",
            self.views.len(),
            self.train_views,
            self.method,
            self.whole.psnr,
            self.whole.ssim
        )?;
        writeln!(
            f,
            "inside the silhouette: PSNR {:.2} dB, SSIM {:.3}; coverage IoU mean {:.3}, worst {:.3}",
            self.inside.psnr, self.inside.ssim, self.coverage_iou, self.coverage_iou_worst
        )?;
        writeln!(
            f,
            "baselines, whole image: rough render {:.2} dB / {:.3}, nearest training photo {:.2} dB / {:.3}",
            self.rough.psnr, self.rough.ssim, self.nearest_photo.psnr, self.nearest_photo.ssim
        )?;
        write!(
            f,
            "model {:.2} s, a view {:.2} s (median)",
            self.model_secs, self.view_secs_median
        )
    }
}

impl Dataset {
    /// Makes every view of `test` (its cameras, photos and silhouettes; loaded over the same
    /// background) from `model` and these photos, and scores it. `each(i)` is called after
    /// view `i`; `keep(i)` says whether to return view `i`'s images.
    pub fn score_test_set(
        &self,
        model: &VoxelModel,
        test: &Dataset,
        view: &ViewParams,
        each: &mut dyn FnMut(usize),
    ) -> crate::Result<(Vec<TestView>, Vec<TestImages>)> {
        let centre = model_centre(model);
        let mut out = Vec::with_capacity(test.cams.len());
        let mut images = Vec::with_capacity(test.cams.len());
        for (i, cam) in test.cams.iter().enumerate() {
            let truth = &test.images[i];
            let (w, h) = truth.dimensions();
            let t = Instant::now();
            let v = novel_view_in(
                model,
                &self.cams,
                &self.images,
                Some(&self.masks),
                cam,
                w,
                h,
                view,
            )?;
            let secs = t.elapsed().as_secs_f64();
            let coverage = &v.rough.coverage;
            let made = placed(&v.guided, coverage, self.background).into_owned();
            let rough = placed(&v.rough.image, coverage, self.background);
            let nearest = nearest_by_direction(&self.cams, cam, &centre, 1)[0];
            let nearest_photo = if self.images[nearest].dimensions() == (w, h) {
                rgb_score(&self.images[nearest], truth, None)?
            } else {
                RgbScore {
                    psnr: f64::NAN,
                    ssim: f64::NAN,
                }
            };
            let sil = &test.score_masks[i];
            out.push(TestView {
                name: cam.name.clone(),
                whole: rgb_score(&made, truth, None)?,
                inside: rgb_score(&made, truth, Some(sil))?,
                rough: rgb_score(&rough, truth, None)?,
                nearest_photo,
                coverage_iou: crate::pipeline::iou(coverage, sil),
                references: v
                    .references
                    .iter()
                    .map(|&r| self.cams[r].name.clone())
                    .collect(),
                secs,
            });
            images.push(TestImages {
                truth: truth.clone(),
                view: made,
            });
            each(i);
        }
        Ok((out, images))
    }
}

/// A contact sheet of `views` (indices into `images`), one row each: truth, new view, error
/// map (the absolute error summed over RGB, x4/3, as the leave-one-out's).
pub fn contact_sheet(images: &[TestImages], views: &[usize]) -> RgbImage {
    let (w, h) = images.first().map_or((1, 1), |i| i.truth.dimensions());
    let mut sheet =
        RgbImage::from_pixel(3 * w, (views.len().max(1) as u32) * h, image::Rgb([255; 3]));
    let all = Mask::from_index_fn(w, h, |_| true);
    for (row, &i) in views.iter().enumerate() {
        let im = &images[i];
        if im.truth.dimensions() != (w, h) {
            continue;
        }
        let err = crate::pipeline::error_map(&im.view, &im.truth, &all);
        for (col, img) in [&im.truth, &im.view, &err].into_iter().enumerate() {
            image::imageops::replace(
                &mut sheet,
                img,
                (col as u32 * w) as i64,
                (row as u32 * h) as i64,
            );
        }
    }
    sheet
}

/// Writes a test-set evaluation into the fresh folder `dir`: every view (`<photo stem>.png`),
/// `contact_sheet.png` of the `worst` views, `eval.json` (the summary with every view).
pub fn write_test_outputs(
    dir: &Path,
    summary: &TestSummary,
    images: &[TestImages],
    worst: usize,
) -> Result<(), DataError> {
    let save = |name: String, img: &RgbImage| {
        let p = dir.join(name);
        img.save(&p).map_err(|e| path_err(&p, e.to_string()))
    };
    let order: Vec<usize> = summary.worst_first().into_iter().take(worst).collect();
    save("contact_sheet.png".into(), &contact_sheet(images, &order))?;
    for (i, (v, im)) in summary.views.iter().zip(images).enumerate() {
        let stem = Path::new(&v.name)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        save(format!("{i:03}_{stem}.png"), &im.view)?;
    }
    write_json(&dir.join("eval.json"), summary)
}
