//! NeRF transforms files (testdata/nerf-lego: the sparse-view benchmark's 8 training views of
//! the NeRF synthetic "lego", RGBA 400x400, `transforms_train.json` and the 25 test views in
//! `transforms_test.json`), loaded through `Dataset::load` / `Dataset::load_set` as `vt fv`
//! does.
//!
//! The truth the cameras are held to is independent of vt's reader: the frames' JSON is read
//! here with serde_json and the geometry is checked against what the NeRF format says a pose
//! means (the camera's centre is the matrix's last column, it looks down the matrix's -z column,
//! its image "up" is the +y column, the focal length is `0.5 * W / tan(0.5 * camera_angle_x)`);
//! and the photos' own alpha silhouettes, which were rendered from those poses, must agree with
//! each other through the cameras (each view's silhouette against the visual hull of the
//! others), while one camera read the wrong way round must disagree. The silhouettes and the
//! composited colours are checked against the PNGs decoded here. Also: an instant-ngp /
//! nerfstudio style file (`fl_x fl_y cx cy w h`, `file_path` with its extension) gives the
//! same cameras, `--views` picks views, and bad files are refused in one line naming the file.

use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Matrix4, Vector3};
use serde_json::{json, Value};
use vt_fv::composite::Background;
use vt_fv::dataset::{CameraFormat, DataError, DataOptions, Dataset};
use vt_fv::hull::{silhouette_agreement, Aabb};
use vt_fv::Camera;

fn lego() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../testdata/nerf-lego")
}

/// The training views in `transforms_train.json`'s order (testdata/nerf-lego/README.md).
const TRAIN: [&str; 8] = [
    "r_26", "r_86", "r_2", "r_55", "r_75", "r_93", "r_16", "r_73",
];
/// The test views in `transforms_test.json`'s order.
/// The test views the checks below pair up: `r_0`, `r_80`, `r_104` (indices in the test file,
/// whose views are every 8th of the 200: `r_0`, `r_8`, ..., `r_192`).
const TEST: [usize; 3] = [0, 10, 13];

/// The lowest IoU a correctly calibrated lego view is allowed (each view's alpha silhouette
/// against the visual hull of the others, 64 voxels along the volume found from the
/// silhouettes). Measured: the 8 training views score 0.77-0.93; the same view with its camera
/// seeing it upside down 0.46, looking away 0.
const AGREE: f64 = 0.7;

/// The lowest IoU of a test view's silhouette against the hull of the 8 training views.
/// Measured 0.70-0.90 (r_80 looks from where few training views do); a test camera paired
/// with another test view's photo scores 0.33-0.50.
const TEST_AGREE: f64 = 0.6;

/// The box the NeRF synthetic scenes lie in (their loaders' `[-1.5, 1.5]^3`), independent of
/// the cameras.
fn scene_box() -> Aabb {
    Aabb::new(Vector3::repeat(-1.5), Vector3::repeat(1.5))
}

fn read_json(p: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

/// A frame's `transform_matrix` read here.
fn c2w(frame: &Value) -> Matrix4<f64> {
    let rows = frame["transform_matrix"].as_array().unwrap();
    Matrix4::from_fn(|r, c| rows[r][c].as_f64().unwrap())
}

fn load(dir: &Path, opt: &DataOptions) -> Dataset {
    Dataset::load(dir, opt).unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
}

fn views(v: &[&str]) -> DataOptions {
    DataOptions {
        views: v.iter().map(|s| s.to_string()).collect(),
        ..Default::default()
    }
}

/// The error loading `dir` with `opt`: one line.
fn err_with(dir: &Path, opt: &DataOptions) -> String {
    let e: DataError = Dataset::load(dir, opt).unwrap_err();
    let s = e.to_string();
    eprintln!("refused: {s}");
    assert!(!s.contains('\n'), "one line: {s}");
    s
}

fn err(dir: &Path) -> String {
    err_with(dir, &DataOptions::default())
}

/// The geometry a NeRF pose means, checked on vt's camera: the centre, the viewing direction
/// (-z column), image right (+x column) and image up (+y column); `k` as given.
fn assert_camera_means_pose(cam: &Camera, m: &Matrix4<f64>, f: f64, (cx, cy): (f64, f64)) {
    let centre = Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]);
    let col = |c: usize| Vector3::new(m[(0, c)], m[(1, c)], m[(2, c)]);
    let (right, up, back) = (col(0), col(1), col(2));
    assert!(
        (cam.centre() - centre).norm() < 1e-5,
        "{}: centre {:?} vs {:?}",
        cam.name,
        cam.centre(),
        centre
    );
    // A point 4 units straight ahead projects onto the principal point at depth 4; 0.1 to the
    // right and 0.1 up move it by f * 0.1 / 4 pixels right and up (rows grow downwards).
    let ahead = centre - back * 4.0;
    let (u, v, z) = cam.project(&ahead).unwrap();
    assert!((z - 4.0).abs() < 1e-5, "{}: depth {z}", cam.name);
    assert!(
        (u - cx).abs() < 1e-3 && (v - cy).abs() < 1e-3,
        "{}: ({u}, {v}) vs ({cx}, {cy})",
        cam.name
    );
    let step = f * 0.1 / 4.0;
    let (u, v, _) = cam.project(&(ahead + right * 0.1)).unwrap();
    assert!(
        (u - (cx + step)).abs() < 1e-3 && (v - cy).abs() < 1e-3,
        "{}: right",
        cam.name
    );
    let (u, v, _) = cam.project(&(ahead + up * 0.1)).unwrap();
    assert!(
        (u - cx).abs() < 1e-3 && (v - (cy - step)).abs() < 1e-3,
        "{}: up",
        cam.name
    );
}

#[test]
fn lego_loads_with_cameras_silhouettes_and_white_background() {
    let dir = lego();
    let d = load(&dir, &DataOptions::default());
    assert_eq!(d.format, CameraFormat::Nerf);
    assert!(
        d.cameras_file.ends_with("transforms_train.json"),
        "{:?}",
        d.cameras_file
    );
    assert_eq!(d.cams.len(), 8);
    assert_eq!(d.images.len(), 8);
    assert_eq!(d.masks.len(), 8);
    assert_eq!(d.size(), (400, 400));
    let names: Vec<&str> = d.cams.iter().map(|c| c.name.as_str()).collect();
    let want: Vec<String> = TRAIN.iter().map(|s| format!("train/{s}.png")).collect();
    assert_eq!(names, want);
    assert_eq!(d.background, Some([255; 3]));
    assert!(d.silhouettes.contains("alpha"), "{}", d.silhouettes);
    assert!(
        d.notes
            .iter()
            .any(|n| n.contains("transforms_train.json") && n.contains("8 frames")),
        "{:?}",
        d.notes
    );

    // Intrinsics and poses as the NeRF format defines them, from the JSON read here.
    let j = read_json(&dir.join("transforms_train.json"));
    let angle = j["camera_angle_x"].as_f64().unwrap();
    let f = 0.5 * 400.0 / (0.5 * angle).tan();
    assert!((f - 555.555).abs() < 0.01, "{f}");
    for (cam, frame) in d.cams.iter().zip(j["frames"].as_array().unwrap()) {
        let k = Matrix3::new(f, 0.0, 199.5, 0.0, f, 199.5, 0.0, 0.0, 1.0);
        assert!((cam.k - k).abs().max() < 1e-9, "{}: K {}", cam.name, cam.k);
        assert_camera_means_pose(cam, &c2w(frame), f, (199.5, 199.5));
    }

    // Silhouettes are the alpha channel (>= 128), colours the photo over white.
    for (i, stem) in TRAIN.iter().enumerate() {
        let rgba = image::open(dir.join(format!("train/{stem}.png")))
            .unwrap()
            .to_rgba8();
        assert_eq!(rgba.dimensions(), (400, 400));
        let m = &d.masks[i];
        let mut inside = 0;
        let mut soft = 0;
        for (x, y, p) in rgba.enumerate_pixels() {
            let a = p.0[3] as f64 / 255.0;
            assert_eq!(m.get(x, y), p.0[3] >= 128, "{stem} ({x}, {y})");
            inside += (p.0[3] >= 128) as usize;
            soft += (p.0[3] > 0 && p.0[3] < 255) as usize;
            let got = d.images[i].get_pixel(x, y).0;
            for c in 0..3 {
                let want = p.0[c] as f64 * a + 255.0 * (1.0 - a);
                assert!(
                    (got[c] as f64 - want).abs() <= 0.5 + 1e-9,
                    "{stem} ({x}, {y}) channel {c}: {} vs {want}",
                    got[c]
                );
            }
        }
        // The bulldozer covers a few percent of the view at least, and not all of it; its
        // edges are anti-aliased.
        let share = inside as f64 / 160_000.0;
        assert!((0.05..0.6).contains(&share), "{stem}: {share}");
        assert!(soft > 100, "{stem}: {soft} soft-edged pixels");
        for (x, y) in [(0, 0), (399, 0), (0, 399), (399, 399)] {
            assert_eq!(rgba.get_pixel(x, y).0[3], 0, "{stem}: corner alpha");
            assert_eq!(d.images[i].get_pixel(x, y).0, [255; 3], "{stem} corner");
        }
        assert_eq!(d.score_masks[i], d.masks[i], "{stem}: scoring silhouette");
    }

    // Other backgrounds: transparent keeps the photo's colours, a colour is composited under.
    let t = load(
        &dir,
        &DataOptions {
            background: Background::Transparent,
            ..Default::default()
        },
    );
    assert_eq!(t.background, None);
    let rgb = image::open(dir.join("train/r_26.png")).unwrap().to_rgb8();
    assert!(t.images[0] == rgb, "transparent: the photo's own colours");
    assert!(t.masks == d.masks);
    let blue = load(
        &dir,
        &DataOptions {
            background: Background::Colour([0, 0, 255]),
            ..Default::default()
        },
    );
    assert_eq!(blue.background, Some([0, 0, 255]));
    assert_eq!(blue.images[3].get_pixel(0, 0).0, [0, 0, 255]);
    assert_eq!(blue.images[3].get_pixel(399, 399).0, [0, 0, 255]);
    assert!(blue.masks == d.masks);
}

/// The cameras agree with the photos: every view's silhouette matches the visual hull of the
/// others (in the volume found from the silhouettes; in the scene box the figures are lower, as
/// parts of the box lie outside some views and are not carved by them); each test view (a
/// second file) agrees with the hull of the 8 training views.
#[test]
fn lego_cameras_make_the_silhouettes_agree() {
    let d = load(&lego(), &DataOptions::default());
    let found = d.volume(None).unwrap();
    // The found volume holds the bulldozer: the origin, inside the scene box, a sizeable box.
    let sb = scene_box();
    for a in 0..3 {
        assert!(
            found.min[a] >= sb.min[a] && found.max[a] <= sb.max[a],
            "{found:?}"
        );
        assert!(found.min[a] < -0.3 && found.max[a] > 0.3, "{found:?}");
    }
    let iou = silhouette_agreement(&d.cams, &d.masks, found, 64).unwrap();
    eprintln!("found volume {found:?}: {iou:.3?}");
    for (c, v) in d.cams.iter().zip(&iou) {
        assert!(*v > AGREE, "{} IoU {v:.3}", c.name);
    }
    let iou = silhouette_agreement(&d.cams, &d.masks, sb, 64).unwrap();
    eprintln!("scene box: {iou:.3?}");
    for (c, v) in d.cams.iter().zip(&iou) {
        assert!(*v > 0.5, "scene box: {} IoU {v:.3}", c.name);
    }

    let test = Dataset::load_set(
        &lego().join("transforms_test.json"),
        &DataOptions::default(),
    )
    .unwrap();
    // Each test camera with its own photo's silhouette, and (a control) with the next one's.
    let against_training = |i: usize, m: usize| {
        let mut cams = d.cams.clone();
        let mut masks = d.masks.clone();
        cams.push(test.cams[i].clone());
        masks.push(test.masks[m].clone());
        silhouette_agreement(&cams, &masks, found, 64).unwrap()[8]
    };
    for (n, &i) in TEST.iter().enumerate() {
        let other = TEST[(n + 1) % 3];
        let (own, wrong) = (against_training(i, i), against_training(i, other));
        let name = &test.cams[i].name;
        eprintln!("{name} against the training views: IoU {own:.3}; with photo {other}'s silhouette {wrong:.3}");
        assert!(
            own > TEST_AGREE,
            "{name} against the training views: IoU {own:.3}"
        );
        assert!(
            wrong < TEST_AGREE && wrong < own - 0.2,
            "{name} with photo {other}'s silhouette: IoU {wrong:.3} (own {own:.3})"
        );
    }
}

/// Negative controls: the same check catches one camera read the wrong way round.
#[test]
fn a_camera_read_the_wrong_way_round_disagrees() {
    let dir = lego();
    let d = load(&dir, &DataOptions::default());
    // The volume as found with the right cameras: any difference below is the camera's.
    let found = d.volume(None).unwrap();
    let agreed = silhouette_agreement(&d.cams, &d.masks, found, 64).unwrap();
    let j = read_json(&dir.join("transforms_train.json"));
    let frames = j["frames"].as_array().unwrap();
    let k = 3;
    let m = c2w(&frames[k]);
    let rot: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let centre = Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]);
    // vt's camera from a camera-to-world rotation in vt's axes (x right, y down, +z ahead).
    let cam_from = |r_c2w: Matrix3<f64>| {
        let r = r_c2w.transpose();
        Camera::new(d.cams[k].name.clone(), d.cams[k].k, r, -(r * centre)).unwrap()
    };
    // The right reading (y and z flipped from OpenGL's axes) gives vt's camera back...
    let right = cam_from(rot * Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0)));
    assert!((right.projection() - d.cams[k].projection()).abs().max() < 1e-9);
    // ...the axes not flipped look away from the object; x and z flipped instead of y and z
    // see it upside down.
    for (what, r_c2w) in [
        ("axes not flipped", rot),
        (
            "x and z flipped",
            rot * Matrix3::from_diagonal(&Vector3::new(-1.0, 1.0, -1.0)),
        ),
    ] {
        let mut cams = d.cams.clone();
        cams[k] = cam_from(r_c2w);
        let iou = silhouette_agreement(&cams, &d.masks, found, 64).unwrap();
        eprintln!("{what}: {iou:.3?}");
        assert!(
            agreed[k] > AGREE && iou[k] < 0.5,
            "{what}: view {k} IoU {:.3}, {:.3} with the right camera",
            iou[k],
            agreed[k]
        );
        // The check names the view, not the others: they still agree among themselves
        // (the camera looking away carves nothing; the upside-down one carves a little).
        let others_ok = (0..8).filter(|&i| i != k && iou[i] > 0.6).count();
        assert!(others_ok >= 6, "{what}: {iou:.3?}");
    }
}

#[test]
fn views_pick_by_index_name_and_stem_in_the_given_order() {
    let dir = lego();
    let d = load(&dir, &views(&["7", "train/r_86.png", "r_55", "0"]));
    let names: Vec<&str> = d.cams.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "train/r_73.png",
            "train/r_86.png",
            "train/r_55.png",
            "train/r_26.png"
        ]
    );
    // The chosen views keep their own cameras and photos.
    let all = load(&dir, &DataOptions::default());
    for (c, i) in d.cams.iter().zip([7, 1, 3, 0]) {
        assert_eq!(c, &all.cams[i]);
    }
    assert!(d.images[0] == all.images[7] && d.masks[2] == all.masks[3]);
    assert!(
        d.notes
            .iter()
            .any(|n| n.contains("4 of 8") && n.contains("train/r_73.png")),
        "{:?}",
        d.notes
    );
    // Every view chosen is no choice at all, apart from the order.
    let every: Vec<String> = (0..8).map(|i| i.to_string()).collect();
    let e = load(
        &dir,
        &DataOptions {
            views: every,
            ..Default::default()
        },
    );
    assert_eq!(e.cams, all.cams);

    // Refusals name the value and the file.
    let e = err_with(&dir, &views(&["8"]));
    assert!(
        e.contains("views")
            && e.contains('8')
            && e.contains("transforms_train.json")
            && e.contains("8 views"),
        "{e}"
    );
    let e = err_with(&dir, &views(&["0", "r_999"]));
    assert!(e.contains("r_999") && e.contains("no view"), "{e}");
    let e = err_with(&dir, &views(&["train/r_0.png"]));
    assert!(e.contains("train/r_0.png") && e.contains("no view"), "{e}");
    let e = err_with(&dir, &views(&["r_26", "0"]));
    assert!(e.contains("chosen twice"), "{e}");
    let e = err_with(&dir, &views(&["2", "train/r_2.png"]));
    assert!(e.contains("chosen twice"), "{e}");
}

#[test]
fn the_test_file_loads_as_a_set() {
    let dir = lego();
    let t = Dataset::load_set(&dir.join("transforms_test.json"), &DataOptions::default()).unwrap();
    assert_eq!(t.format, CameraFormat::Nerf);
    assert!(t.cameras_file.ends_with("transforms_test.json"));
    let names: Vec<&str> = t.cams.iter().map(|c| c.name.as_str()).collect();
    let want: Vec<String> = (0..25).map(|i| format!("test/r_{}.png", 8 * i)).collect();
    assert_eq!(names, want);
    assert_eq!(t.size(), (400, 400));
    assert_eq!(t.background, Some([255; 3]));
    assert_eq!(t.images[0].get_pixel(0, 0).0, [255; 3]);
    let j = read_json(&dir.join("transforms_test.json"));
    let f = 0.5 * 400.0 / (0.5 * j["camera_angle_x"].as_f64().unwrap()).tan();
    for (cam, frame) in t.cams.iter().zip(j["frames"].as_array().unwrap()) {
        assert_camera_means_pose(cam, &c2w(frame), f, (199.5, 199.5));
    }
    // The folder itself is the training set; a missing file and a non-JSON file are refused.
    let d = Dataset::load_set(&dir, &DataOptions::default()).unwrap();
    assert_eq!(d.cams.len(), 8);
    let e = Dataset::load_set(&dir.join("transforms_val.json"), &DataOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("transforms_val.json") && !e.contains('\n'),
        "{e}"
    );
    let e = Dataset::load_set(&dir.join("README.md"), &DataOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("README.md") && e.contains(".json"), "{e}");
}

/// A folder in instant-ngp / nerfstudio's layout: `transforms.json` with `fl_x fl_y cx cy w h`
/// (pixel centres at 0.5), `camera_model`, `file_path` with its extension, photos in `images/`.
struct Ngp {
    _tmp: tempfile::TempDir,
    dir: PathBuf,
    json: Value,
}

impl Ngp {
    fn write(&self, v: &Value) {
        std::fs::write(
            self.dir.join("transforms.json"),
            serde_json::to_string_pretty(v).unwrap(),
        )
        .unwrap();
    }
}

/// The lego's training views as instant-ngp writes them (the same intrinsics: f at 400 px,
/// principal point at the centre, 200 in the 0.5 convention).
fn ngp() -> Ngp {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("ngp");
    std::fs::create_dir_all(dir.join("images")).unwrap();
    let train = read_json(&lego().join("transforms_train.json"));
    let f = 0.5 * 400.0 / (0.5 * train["camera_angle_x"].as_f64().unwrap()).tan();
    let mut frames = Vec::new();
    for (stem, frame) in TRAIN.iter().zip(train["frames"].as_array().unwrap()) {
        std::fs::copy(
            lego().join(format!("train/{stem}.png")),
            dir.join(format!("images/{stem}.png")),
        )
        .unwrap();
        frames.push(json!({
            "file_path": format!("images/{stem}.png"),
            "transform_matrix": frame["transform_matrix"].clone(),
        }));
    }
    let json = json!({
        "camera_model": "OPENCV",
        "fl_x": f, "fl_y": f, "cx": 200.0, "cy": 200.0, "w": 400, "h": 400,
        "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0,
        "frames": frames,
    });
    let n = Ngp {
        _tmp: tmp,
        dir,
        json,
    };
    n.write(&n.json);
    n
}

#[test]
fn an_instant_ngp_file_gives_the_same_cameras() {
    let n = ngp();
    let d = load(&n.dir, &DataOptions::default());
    assert_eq!(d.format, CameraFormat::Nerf);
    assert!(d.cameras_file.ends_with("transforms.json"));
    assert_eq!(d.background, Some([255; 3]));
    let lego = load(&lego(), &DataOptions::default());
    assert_eq!(d.cams.len(), 8);
    for (a, b) in d.cams.iter().zip(&lego.cams) {
        assert_eq!(a.name, b.name.replace("train/", "images/"));
        let rel = (a.projection() - b.projection()).abs().max() / b.projection().abs().max();
        assert!(rel < 1e-12, "{}: P differs by {rel:e}", a.name);
    }
    assert!(d.images == lego.images && d.masks == lego.masks);
    assert!(
        !d.notes.iter().any(|s| s.contains("resampled")),
        "no lens, same size: nothing resampled: {:?}",
        d.notes
    );

    // cx, cy lose 0.5 (vt's first pixel centre is at 0); fl_x, fl_y are kept per axis.
    let mut v = n.json.clone();
    v["fl_x"] = json!(560.0);
    v["fl_y"] = json!(550.0);
    v["cx"] = json!(201.25);
    v["cy"] = json!(198.75);
    n.write(&v);
    let d = load(&n.dir, &views(&["r_2"]));
    let k = Matrix3::new(560.0, 0.0, 200.75, 0.0, 550.0, 198.25, 0.0, 0.0, 1.0);
    assert!((d.cams[0].k - k).abs().max() < 1e-12, "K {}", d.cams[0].k);
    assert_eq!(d.cams[0].name, "images/r_2.png");

    // A frame's own intrinsics override the shared ones for that frame only.
    let mut v = n.json.clone();
    v["frames"][1]["fl_x"] = json!(600.0);
    v["frames"][1]["cx"] = json!(190.5);
    n.write(&v);
    let d = load(&n.dir, &DataOptions::default());
    assert_eq!((d.cams[1].k[(0, 0)], d.cams[1].k[(0, 2)]), (600.0, 190.0));
    assert!((d.cams[1].k[(1, 1)] - lego.cams[1].k[(1, 1)]).abs() < 1e-9);
    assert_eq!(d.cams[0].k, lego.cams[0].k);

    // Intrinsics given for 800x800 (the NeRF data's full size) fit the 400x400 photos: f and
    // the principal point halve, pixel centres kept (400 -> 399.5 at 800 -> 199.5 at 400).
    let mut v = n.json.clone();
    let f = lego.cams[0].k[(0, 0)];
    v["fl_x"] = json!(2.0 * f);
    v["fl_y"] = json!(2.0 * f);
    v["cx"] = json!(400.0);
    v["cy"] = json!(400.0);
    v["w"] = json!(800);
    v["h"] = json!(800);
    n.write(&v);
    let d = load(&n.dir, &DataOptions::default());
    for (a, b) in d.cams.iter().zip(&lego.cams) {
        assert!((a.k - b.k).abs().max() < 1e-9, "{}: K {}", a.name, a.k);
    }
    assert!(d.images == lego.images);
    assert!(
        d.notes.iter().any(|s| s.contains("recorded size")),
        "{:?}",
        d.notes
    );
}

#[test]
fn bad_transforms_files_are_one_line_naming_the_file() {
    let n = ngp();
    let file = "transforms.json";
    // Not JSON.
    std::fs::write(n.dir.join(file), "{\"frames\": [\n  {\"file_path\": ").unwrap();
    let e = err(&n.dir);
    assert!(
        e.contains(file) && e.contains("not valid JSON") && e.contains("line"),
        "{e}"
    );
    // A frame's photo is missing.
    n.write(&n.json);
    std::fs::remove_file(n.dir.join("images/r_55.png")).unwrap();
    let e = err(&n.dir);
    assert!(
        e.contains(file) && e.contains("frame 3") && e.contains("images/r_55.png"),
        "{e}"
    );
    std::fs::copy(lego().join("train/r_55.png"), n.dir.join("images/r_55.png")).unwrap();
    assert_eq!(load(&n.dir, &DataOptions::default()).cams.len(), 8);
    // A file_path leaving the folder, though the photo is there.
    std::fs::copy(
        lego().join("train/r_2.png"),
        n.dir.parent().unwrap().join("r_2.png"),
    )
    .unwrap();
    let mut v = n.json.clone();
    v["frames"][2]["file_path"] = json!("../r_2.png");
    n.write(&v);
    let e = err(&n.dir);
    assert!(
        e.contains(file)
            && e.contains("frame 2")
            && e.contains("../r_2.png")
            && e.contains("outside"),
        "{e}"
    );
    let mut v = n.json.clone();
    v["frames"][2]["file_path"] = json!("images/../../r_2.png");
    n.write(&v);
    let e = err(&n.dir);
    assert!(e.contains(file) && e.contains("outside"), "{e}");
    // A distortion vt does not model (k3), shared or in a frame.
    let mut v = n.json.clone();
    v["k3"] = json!(0.01);
    n.write(&v);
    let e = err(&n.dir);
    assert!(e.contains(file) && e.contains("k3"), "{e}");
    let mut v = n.json.clone();
    v["k3"] = json!(0.0);
    n.write(&v);
    assert_eq!(
        load(&n.dir, &DataOptions::default()).cams.len(),
        8,
        "k3 = 0 is fine"
    );
    let mut v = n.json.clone();
    v["frames"][5]["k3"] = json!(-0.2);
    n.write(&v);
    let e = err(&n.dir);
    assert!(
        e.contains(file) && e.contains("frame 5") && e.contains("k3"),
        "{e}"
    );
    // A fisheye.
    let mut v = n.json.clone();
    v["camera_model"] = json!("OPENCV_FISHEYE");
    n.write(&v);
    let e = err(&n.dir);
    assert!(e.contains(file) && e.contains("OPENCV_FISHEYE"), "{e}");
    // A pose that is not a rotation names the file and the photo.
    let mut v = n.json.clone();
    v["frames"][4]["transform_matrix"][0][0] = json!(2.0);
    n.write(&v);
    let e = err(&n.dir);
    assert!(e.contains(file) && e.contains("images/r_75.png"), "{e}");
    n.write(&n.json);

    // Cameras in more than one place: a par file, a COLMAP model, a second transforms file.
    let par = n.dir.join("lego_par.txt");
    std::fs::write(&par, "0\n").unwrap();
    let e = err(&n.dir);
    assert!(
        e.contains("more than one place") && e.contains("lego_par.txt") && e.contains(file),
        "{e}"
    );
    std::fs::remove_file(&par).unwrap();
    std::fs::create_dir_all(n.dir.join("sparse/0")).unwrap();
    std::fs::write(n.dir.join("sparse/0/cameras.txt"), "").unwrap();
    std::fs::write(n.dir.join("sparse/0/images.txt"), "").unwrap();
    let e = err(&n.dir);
    assert!(
        e.contains("more than one place") && e.contains("COLMAP") && e.contains(file),
        "{e}"
    );
    std::fs::remove_dir_all(n.dir.join("sparse")).unwrap();
    std::fs::copy(
        lego().join("transforms_train.json"),
        n.dir.join("transforms_train.json"),
    )
    .unwrap();
    let e = err(&n.dir);
    assert!(
        e.contains("more than one place")
            && e.contains("transforms_train.json")
            && e.contains(file),
        "{e}"
    );
    std::fs::remove_file(n.dir.join("transforms_train.json")).unwrap();
    assert_eq!(load(&n.dir, &DataOptions::default()).cams.len(), 8);
}

/// A stem shared by two photos in different folders is ambiguous; the full name is not.
#[test]
fn an_ambiguous_stem_is_refused() {
    let n = ngp();
    std::fs::create_dir_all(n.dir.join("more")).unwrap();
    std::fs::copy(lego().join("train/r_26.png"), n.dir.join("more/r_26.png")).unwrap();
    let mut v = n.json.clone();
    let extra = json!({
        "file_path": "more/r_26.png",
        "transform_matrix": v["frames"][0]["transform_matrix"].clone(),
    });
    v["frames"].as_array_mut().unwrap().push(extra);
    n.write(&v);
    let e = err_with(&n.dir, &views(&["r_26", "1", "2"]));
    assert!(
        e.contains("r_26") && e.contains("more than one view"),
        "{e}"
    );
    let d = load(&n.dir, &views(&["more/r_26.png", "images/r_26.png", "1"]));
    let names: Vec<&str> = d.cams.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(
        names,
        ["more/r_26.png", "images/r_26.png", "images/r_86.png"]
    );
    assert_eq!(load(&n.dir, &views(&["8"])).cams[0].name, "more/r_26.png");
}
