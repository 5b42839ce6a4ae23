//! The marking page (`vt mark`): the points that register the views of a System A scene, shown
//! on the views' median backgrounds in the browser, to add, move and delete, with the fit of
//! every neighbour pair recomputed after each change, and saved as a points file that
//! `vt analyze --points` reads.
//!
//! A [`Session`] is the input: one scene directory (its backgrounds, and its points from
//! scene.json: the marked ones, or the virtual points of an automatic registration), or two or
//! more views (videos or frame folders, as `vt analyze` takes them), whose backgrounds are the
//! median of at most [`MEDIAN_SAMPLE`] evenly spaced frames. A points file given at the start
//! replaces the scene's points.
//!
//! The [`Marker`] serves it on 127.0.0.1 through vt-view's HTTP layer, with these routes only:
//!
//! - `GET /`: the page (`mark.html`, one file, no external assets).
//! - `GET /state`: JSON `{width, height, views: [name], points: [[[x, y]]], out, margin}`.
//! - `GET /background/N.png`: view N's background.
//! - `POST /fit` with `{"points": [[[x, y], ...] per view]}` (at most [`MAX_BODY`] bytes): a
//!   [`FitReport`]: per neighbour pair the homography fitted to the points
//!   ([`vt_core::model::fit_model`]), its RMS transfer error and each point's residual, and the
//!   model GRIC selects for the scene ([`vt_core::model::select_model`]), as `vt analyze` would.
//! - `POST /save` with the same body: writes the points file to the `--out` path through
//!   [`vt_io::points::write_points_file`] (atomic; only ever replaces a points file vt wrote).
//!
//! Everything else is 404; other methods 405. Only pages on this server may use it: every
//! request must name it in `Host` (`127.0.0.1:PORT` or `localhost:PORT`, against DNS
//! rebinding; else 403), and POSTs must be `Content-Type: application/json` (else 415), which
//! other sites' pages cannot send without a preflight request, which is refused.

use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use image::RgbImage;
use serde::{Deserialize, Serialize};
use vt_core::analysis::{Frame, FrameRef};
use vt_core::model::{fit_model, select_model, ModelParams, MotionModel};
use vt_core::{Homography, Point};
use vt_io::frames::ViewSource;
use vt_io::scene::SceneFile;

use crate::http::{self, Body, Reply};
use crate::{lock, Error, Result};

const PAGE: &str = include_str!("mark.html");

/// Largest request body `/fit` and `/save` take, bytes.
pub const MAX_BODY: usize = 4 << 20;
/// Most frames of a view its background (median) is taken from, evenly spaced.
pub const MEDIAN_SAMPLE: usize = 64;

/// What is being marked: the views' backgrounds, names and starting points, and where they are
/// saved.
pub struct Session {
    size: (u32, u32),
    names: Vec<String>,
    backgrounds: Vec<RgbImage>,
    points: Vec<Vec<Point>>,
    out: PathBuf,
    inputs: Vec<PathBuf>,
}

impl Session {
    /// Opens the inputs: one scene directory, or two or more views. `start` (a points file)
    /// replaces the scene's points. `out` is checked first, before any decoding: it must be a
    /// path a points file may be written to ([`vt_io::points::check_points_output`]).
    pub fn open(inputs: &[PathBuf], start: Option<&Path>, out: &Path) -> Result<Self> {
        let bad = |path: &Path, message: &str| Error::Input {
            path: path.to_path_buf(),
            message: message.to_string(),
        };
        let Some(first) = inputs.first() else {
            return Err(bad(
                Path::new("."),
                "nothing to mark: give a scene directory or two or more views",
            ));
        };
        for path in inputs.iter().map(PathBuf::as_path).chain(start) {
            if !path.exists() {
                return Err(bad(path, "no such file or directory"));
            }
        }
        if inputs.len() == 1 && !first.join("scene.json").is_file() {
            let why = if first.is_dir() {
                "not a scene directory (no scene.json): give a scene written by `vt analyze`, or two or more views"
            } else {
                "one input must be a scene directory; to mark views, give two or more (videos or frame folders)"
            };
            return Err(bad(first, why));
        }
        if inputs.len() > vt_io::limits::MAX_VIEWS {
            let why = format!(
                "{} views is more than {}",
                inputs.len(),
                vt_io::limits::MAX_VIEWS
            );
            return Err(bad(first, &why));
        }
        let mut all: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
        all.extend(start);
        vt_io::points::check_points_output(out, &all)?;

        let (names, backgrounds, scene_points) = if inputs.len() == 1 {
            open_scene(first)?
        } else {
            open_views(inputs)?
        };
        let size = backgrounds[0].dimensions();
        let points = match start {
            Some(path) => vt_io::points::read_for_views(path, backgrounds.len(), size)?,
            None => scene_points,
        };
        Ok(Self {
            size,
            names,
            backgrounds,
            points,
            out: out.to_path_buf(),
            inputs: all.into_iter().map(Path::to_path_buf).collect(),
        })
    }

    /// Number of views.
    pub fn views(&self) -> usize {
        self.backgrounds.len()
    }

    /// Frame size (width, height).
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// The starting points, per view (empty when there are none).
    pub fn points(&self) -> &[Vec<Point>] {
        &self.points
    }

    /// View `p`'s background.
    pub fn background(&self, p: usize) -> Option<&RgbImage> {
        self.backgrounds.get(p)
    }
}

type Opened = (Vec<String>, Vec<RgbImage>, Vec<Vec<Point>>);

/// A scene directory: its views' names, backgrounds and points.
fn open_scene(dir: &Path) -> Result<Opened> {
    let scene = SceneFile::read(dir)?;
    let m = scene.views.len();
    if m < 2 {
        return Err(Error::Input {
            path: dir.to_path_buf(),
            message: format!("the scene has {m} view; marking links two or more"),
        });
    }
    let mut backgrounds = Vec::with_capacity(m);
    for v in &scene.views {
        let path = dir.join(&v.background);
        let bg = vt_io::frames::read_rgb(&path)?;
        if bg.dimensions() != (scene.width, scene.height) {
            return Err(Error::Input {
                path,
                message: format!(
                    "background is {}x{}, the scene is {}x{}",
                    bg.width(),
                    bg.height(),
                    scene.width,
                    scene.height
                ),
            });
        }
        backgrounds.push(bg);
    }
    let k = scene.views[0].points.len();
    let points = if k >= 4 && scene.views.iter().all(|v| v.points.len() == k) {
        let to_point = |p: &[f64; 2]| Point::new(p[0], p[1]);
        scene
            .views
            .iter()
            .map(|v| v.points.iter().map(to_point).collect())
            .collect()
    } else {
        vec![Vec::new(); m]
    };
    let names = scene.views.iter().map(|v| v.name.clone()).collect();
    Ok((names, backgrounds, points))
}

/// Two or more views: each one's background from at most [`MEDIAN_SAMPLE`] frames.
fn open_views(paths: &[PathBuf]) -> Result<Opened> {
    let mut sources = Vec::with_capacity(paths.len());
    for path in paths {
        sources.push(ViewSource::open(path)?);
    }
    vt_io::frames::common_size(paths, &sources)?;
    let backgrounds = sources
        .iter_mut()
        .map(view_background)
        .collect::<Result<Vec<_>>>()?;
    let names = paths.iter().map(|p| p.display().to_string()).collect();
    Ok((names, backgrounds, vec![Vec::new(); paths.len()]))
}

/// The median of at most [`MEDIAN_SAMPLE`] evenly spaced frames of a view (frames 0, s, 2s, ...
/// for the smallest power of two s that keeps at most that many), decoding the view once and
/// holding only the sample, in the source's own form (4:2:0 for video).
pub fn view_background(source: &mut ViewSource) -> Result<RgbImage> {
    let mut kept: Vec<(usize, Frame)> = Vec::new();
    let mut stride = 1usize;
    source.as_source().for_each_native(&mut |i, frame| {
        if i % stride == 0 {
            kept.push((i, frame.to_owned()));
            if kept.len() > MEDIAN_SAMPLE {
                stride *= 2;
                kept.retain(|(j, _)| j % stride == 0);
            }
        }
        Ok(())
    })?;
    let refs: Vec<FrameRef<'_>> = kept.iter().map(|(_, f)| f.as_ref()).collect();
    Ok(vt_core::median::temporal_median_frames(&refs)?)
}

/// The fit of one neighbour pair `(from, from + 1)`.
#[derive(Debug, Clone, Serialize)]
pub struct PairFit {
    /// The first view of the pair.
    pub from: usize,
    /// RMS transfer error of the points under the fitted homography, pixels (None: no fit).
    pub rms: Option<f64>,
    /// Each point's transfer error `|H x_from - x_(from+1)|`, pixels.
    pub residuals: Vec<Option<f64>>,
    /// The homography `H_(from, from+1)`, row-major.
    pub homography: Option<[[f64; 3]; 3]>,
    /// Why there is no fit.
    pub error: Option<String>,
}

/// The model GRIC selects for the whole scene from these points, as `vt analyze` would.
#[derive(Debug, Clone, Serialize)]
pub struct ModelChoice {
    /// The model's name.
    pub model: String,
    /// Its RMS transfer error per pair, pixels.
    pub rms: Vec<f64>,
}

/// `/fit`'s answer.
#[derive(Debug, Clone, Serialize)]
pub struct FitReport {
    /// Points per view.
    pub points: usize,
    /// One entry per neighbour pair.
    pub pairs: Vec<PairFit>,
    /// The selected model (None: the points do not allow one).
    pub model: Option<ModelChoice>,
    /// Why no model could be selected.
    pub model_error: Option<String>,
}

fn rows(h: &Homography) -> [[f64; 3]; 3] {
    let m = h.matrix();
    [0, 1, 2].map(|r| [m[(r, 0)], m[(r, 1)], m[(r, 2)]])
}

/// Fits every neighbour pair of `points` (one list per view, the same K points in each).
pub fn fit(points: &[Vec<Point>]) -> FitReport {
    let k = points.first().map_or(0, Vec::len);
    let sigma = ModelParams::default().sigma;
    let pairs = points
        .windows(2)
        .enumerate()
        .map(|(from, w)| {
            let no_fit = |error: String| PairFit {
                from,
                rms: None,
                residuals: vec![None; k],
                homography: None,
                error: Some(error),
            };
            if k < 4 {
                return no_fit(format!("{k} points; a homography needs at least 4"));
            }
            match fit_model(MotionModel::Homography, &w[0], &w[1], sigma) {
                Ok(f) => PairFit {
                    from,
                    rms: Some(f.rms),
                    residuals: w[0]
                        .iter()
                        .zip(&w[1])
                        .map(|(a, b)| f.homography.apply(*a).map(|t| (t - b).norm()))
                        .collect(),
                    homography: Some(rows(&f.homography)),
                    error: None,
                },
                Err(e) => no_fit(e.to_string()),
            }
        })
        .collect();
    let refs: Vec<(&[Point], &[Point])> = points
        .windows(2)
        .map(|w| (w[0].as_slice(), w[1].as_slice()))
        .collect();
    let (model, model_error) = if k < 4 {
        (None, Some(format!("{k} points; at least 4 are needed")))
    } else {
        match select_model(&refs, &ModelParams::default()) {
            Ok(s) => (
                Some(ModelChoice {
                    model: s.model.name().to_string(),
                    rms: s.fits.iter().map(|f| f.rms).collect(),
                }),
                None,
            ),
            Err(e) => (None, Some(e.to_string())),
        }
    };
    FitReport {
        points: k,
        pairs,
        model,
        model_error,
    }
}

/// The body of `/fit` and `/save`.
#[derive(Deserialize)]
struct PointsBody {
    points: Vec<Vec<[f64; 2]>>,
}

/// A marker bound to its port, not yet serving.
pub struct Marker {
    listener: std::net::TcpListener,
    port: u16,
    handler: Arc<MarkHandler>,
}

struct MarkHandler {
    /// The `Host` values accepted.
    hosts: [String; 2],
    page: Arc<String>,
    state: Mutex<State>,
    /// PNG of each background, encoded once.
    pngs: Vec<Arc<Vec<u8>>>,
    size: (u32, u32),
    names: Vec<String>,
    out: PathBuf,
    inputs: Vec<PathBuf>,
    /// Held while saving: saves never overlap.
    saving: Mutex<()>,
}

struct State {
    /// The latest points the page sent (a reload shows them).
    points: Vec<Vec<Point>>,
}

impl Marker {
    /// Encodes the backgrounds and binds 127.0.0.1:`port` (0 = any free port).
    pub fn bind(session: Session, port: u16) -> Result<Self> {
        let pngs = session
            .backgrounds
            .iter()
            .map(|bg| png(bg).map(Arc::new))
            .collect::<Result<Vec<_>>>()?;
        let (listener, port) = http::bind(port)?;
        let handler = Arc::new(MarkHandler {
            hosts: [format!("127.0.0.1:{port}"), format!("localhost:{port}")],
            page: Arc::new(PAGE.to_string()),
            state: Mutex::new(State {
                points: session.points,
            }),
            pngs,
            size: session.size,
            names: session.names,
            out: session.out,
            inputs: session.inputs,
            saving: Mutex::new(()),
        });
        Ok(Self {
            listener,
            port,
            handler,
        })
    }

    /// The port it listens on.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// Serves connections until the process ends.
    pub fn serve(self) {
        let limits = http::Limits {
            max_body: MAX_BODY,
            // /fit runs the model fits on the connection's thread.
            stack: 4 << 20,
        };
        http::serve(self.listener, limits, self.handler);
    }
}

fn png(img: &RgbImage) -> Result<Vec<u8>> {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    use image::ImageEncoder;
    let mut out = Vec::new();
    PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Adaptive)
        .write_image(
            img.as_raw(),
            img.width(),
            img.height(),
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| Error::Input {
            path: PathBuf::from("background"),
            message: format!("cannot encode as PNG: {e}"),
        })?;
    Ok(out)
}

fn pairs_of(points: &[Vec<Point>]) -> Vec<Vec<[f64; 2]>> {
    points
        .iter()
        .map(|v| v.iter().map(|p| [p.x, p.y]).collect())
        .collect()
}

impl MarkHandler {
    /// The points of a `/fit` or `/save` body, checked: one list per view, the same number of
    /// finite points in each, at most [`vt_io::limits::MAX_POINTS`].
    fn parse_points(&self, body: &[u8]) -> std::result::Result<Vec<Vec<Point>>, String> {
        let body: PointsBody = serde_json::from_slice(body)
            .map_err(|e| format!("expected {{\"points\": [[[x, y], ...] per view]}}: {e}"))?;
        let m = self.names.len();
        if body.points.len() != m {
            return Err(format!(
                "{} lists of points for {m} views",
                body.points.len()
            ));
        }
        let k = body.points[0].len();
        if let Some(p) = body.points.iter().position(|v| v.len() != k) {
            let n = body.points[p].len();
            return Err(format!("view {p} has {n} points, view 0 has {k}"));
        }
        if k > vt_io::limits::MAX_POINTS {
            let max = vt_io::limits::MAX_POINTS;
            return Err(format!("{k} points, more than the {max} vt reads"));
        }
        if body
            .points
            .iter()
            .flatten()
            .flatten()
            .any(|c| !c.is_finite())
        {
            return Err("a point is not finite".into());
        }
        Ok(body
            .points
            .iter()
            .map(|v| v.iter().map(|c| Point::new(c[0], c[1])).collect())
            .collect())
    }

    /// Saves `points` to the `--out` path, checked as `vt analyze` will read them.
    fn save(&self, points: &[Vec<Point>]) -> std::result::Result<(), String> {
        let (w, h) = (self.size.0 as f64, self.size.1 as f64);
        let margin = vt_io::points::POINT_MARGIN;
        let (mx, my) = (margin * w, margin * h);
        for (p, view) in points.iter().enumerate() {
            for (k, pt) in view.iter().enumerate() {
                if pt.x < -0.5 - mx
                    || pt.x > w - 0.5 + mx
                    || pt.y < -0.5 - my
                    || pt.y > h - 0.5 + my
                {
                    return Err(format!(
                        "view {p} point {k} ({:.1}, {:.1}) is outside the {}x{} frame (at most {:.0}% beyond its edges)",
                        pt.x, pt.y, self.size.0, self.size.1, 100.0 * margin
                    ));
                }
            }
        }
        let inputs: Vec<&Path> = self.inputs.iter().map(PathBuf::as_path).collect();
        let _saving = lock(&self.saving);
        vt_io::points::write_points_file(&self.out, points, &inputs).map_err(|e| e.to_string())
    }
}

impl http::Handler for MarkHandler {
    fn handle(&self, req: &http::Request, _conn: &mut TcpStream) -> Reply {
        use http::Method::{Get, Post};
        let path = req.path.as_str();
        let method = match path {
            "/fit" | "/save" => Post,
            _ => Get,
        };
        let known =
            matches!(path, "/" | "/state" | "/fit" | "/save") || background_index(path).is_some();
        if !req.host.as_ref().is_some_and(|h| self.hosts.contains(h)) {
            let want = &self.hosts[0];
            return Reply::text(403, format!("only pages from {want} may use this server"));
        }
        if known && req.method != method {
            return Reply::text(405, format!("{path} takes {method:?} requests"));
        }
        let json = req
            .content_type
            .as_deref()
            .is_some_and(|t| t.starts_with("application/json"));
        if method == Post && !json {
            return Reply::text(415, format!("{path} takes application/json"));
        }
        match path {
            "/" => Reply::new(
                200,
                "text/html; charset=utf-8",
                Body::Text(self.page.clone()),
            ),
            "/state" => {
                let points = pairs_of(&lock(&self.state).points);
                Reply::json(
                    200,
                    &serde_json::json!({
                        "width": self.size.0,
                        "height": self.size.1,
                        "views": self.names,
                        "points": points,
                        "out": self.out.display().to_string(),
                        "margin": vt_io::points::POINT_MARGIN,
                    }),
                )
            }
            "/fit" => match self.parse_points(&req.body) {
                Ok(points) => {
                    let report = fit(&points);
                    lock(&self.state).points = points;
                    Reply::json(200, &report)
                }
                Err(e) => Reply::text(400, e),
            },
            "/save" => match self.parse_points(&req.body) {
                Ok(points) => {
                    let saved = self.save(&points);
                    lock(&self.state).points = points;
                    match saved {
                        Ok(()) => {
                            let st = lock(&self.state);
                            Reply::json(
                                200,
                                &serde_json::json!({
                                    "saved": self.out.display().to_string(),
                                    "views": st.points.len(),
                                    "points": st.points.first().map_or(0, Vec::len),
                                }),
                            )
                        }
                        Err(e) => Reply::text(409, e),
                    }
                }
                Err(e) => Reply::text(400, e),
            },
            _ => match background_index(path).and_then(|p| self.pngs.get(p)) {
                Some(png) => Reply::new(200, "image/png", Body::Shared(png.clone())),
                None => Reply::not_found(),
            },
        }
    }
}

/// N of `/background/N.png` (digits only, at most 6).
fn background_index(path: &str) -> Option<usize> {
    let n = path.strip_prefix("/background/")?.strip_suffix(".png")?;
    if n.is_empty() || n.len() > 6 || !n.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    n.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_report_residuals_and_refuse_too_few_points() {
        let a = vec![
            Point::new(10.0, 10.0),
            Point::new(100.0, 12.0),
            Point::new(95.0, 80.0),
            Point::new(12.0, 70.0),
            Point::new(50.0, 40.0),
        ];
        let mut b: Vec<Point> = a.iter().map(|p| Point::new(p.x - 4.0, p.y + 1.0)).collect();
        let r = fit(&[a.clone(), b.clone()]);
        assert_eq!(r.points, 5);
        assert!(r.pairs[0].rms.unwrap() < 1e-6, "{r:?}");
        assert_eq!(r.model.as_ref().unwrap().model, "translation");
        // One point moved: its residual is the largest.
        b[4].x += 6.0;
        let r = fit(&[a.clone(), b.clone()]);
        let res: Vec<f64> = r.pairs[0].residuals.iter().map(|e| e.unwrap()).collect();
        let worst = (0..5).max_by(|&i, &j| res[i].total_cmp(&res[j])).unwrap();
        assert_eq!(worst, 4, "{res:?}");
        assert!(r.pairs[0].rms.unwrap() > 0.5);
        let r = fit(&[a[..3].to_vec(), b[..3].to_vec()]);
        assert!(r.pairs[0].rms.is_none() && r.pairs[0].error.is_some());
        assert!(r.model.is_none());
        assert_eq!(background_index("/background/12.png"), Some(12));
        assert_eq!(background_index("/background/../x.png"), None);
        assert_eq!(background_index("/background/.png"), None);
    }
}
