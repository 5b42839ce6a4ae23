//! The same cameras in every format vt reads give the same model: templeSparseRing's par file
//! (testdata/) written here as a COLMAP text model, a COLMAP binary model and one 3x4
//! projection matrix per photo (writers independent of vt-fv's readers, following COLMAP's
//! format page), each loaded through `Dataset::load` like `vt fv` does, must give the same
//! cameras, byte-identical photos and silhouettes, and identical voxel sets and colours. Also:
//! the data folder's bad inputs are one line naming the file and what is wrong.

use std::path::{Path, PathBuf};

use nalgebra::{Rotation3, UnitQuaternion, Vector3};
use vt_fv::camera::parse_par;
use vt_fv::dataset::{
    build_summarised, CameraFormat, DataError, DataOptions, Dataset, ModelParams,
};
use vt_fv::hull::Aabb;
use vt_fv::Camera;

fn temple() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../testdata/templeSparseRing")
}

fn par_cams() -> Vec<Camera> {
    parse_par(&std::fs::read_to_string(temple().join("templeSR_par.txt")).unwrap()).unwrap()
}

/// Links (or copies) the temple's photos into `dir`.
fn photos_into(dir: &Path, cams: &[Camera]) {
    std::fs::create_dir_all(dir).unwrap();
    for c in cams {
        let (from, to) = (temple().join(&c.name), dir.join(&c.name));
        if std::fs::hard_link(&from, &to).is_err() {
            std::fs::copy(&from, &to).unwrap();
        }
    }
}

/// COLMAP's quaternion (w, x, y, z) of a rotation matrix.
fn quat(c: &Camera) -> [f64; 4] {
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&c.r));
    [q.w, q.i, q.j, q.k]
}

/// COLMAP's PINHOLE parameters: fx fy cx cy, with the first pixel's centre at (0.5, 0.5).
fn pinhole(c: &Camera) -> [f64; 4] {
    assert_eq!(c.k[(0, 1)], 0.0, "COLMAP has no skew");
    [
        c.k[(0, 0)],
        c.k[(1, 1)],
        c.k[(0, 2)] + 0.5,
        c.k[(1, 2)] + 0.5,
    ]
}

/// `cameras.txt` and `images.txt`, one PINHOLE camera per image (ids from 1), no 2-D points.
fn colmap_text(cams: &[Camera], w: u32, h: u32) -> (String, String) {
    let mut c = String::from("# Camera list with one line of data per camera:\n");
    c += &format!("# Number of cameras: {}\n", cams.len());
    let mut m = String::from("# Image list with two lines of data per image:\n");
    m += &format!(
        "# Number of images: {}, mean observations per image: 0\n",
        cams.len()
    );
    for (i, cam) in cams.iter().enumerate() {
        let [fx, fy, cx, cy] = pinhole(cam);
        c += &format!("{} PINHOLE {w} {h} {fx:?} {fy:?} {cx:?} {cy:?}\n", i + 1);
        let [qw, qx, qy, qz] = quat(cam);
        let t = cam.t;
        m += &format!(
            "{} {qw:?} {qx:?} {qy:?} {qz:?} {:?} {:?} {:?} {} {}\n\n",
            i + 1,
            t.x,
            t.y,
            t.z,
            i + 1,
            cam.name
        );
    }
    (c, m)
}

/// `cameras.bin` and `images.bin` (little endian, COLMAP's layout).
fn colmap_binary(cams: &[Camera], w: u32, h: u32) -> (Vec<u8>, Vec<u8>) {
    let (mut c, mut m) = (Vec::new(), Vec::new());
    c.extend((cams.len() as u64).to_le_bytes());
    m.extend((cams.len() as u64).to_le_bytes());
    for (i, cam) in cams.iter().enumerate() {
        let id = (i + 1) as u32;
        c.extend(id.to_le_bytes());
        c.extend(1i32.to_le_bytes()); // PINHOLE
        c.extend((w as u64).to_le_bytes());
        c.extend((h as u64).to_le_bytes());
        for p in pinhole(cam) {
            c.extend(p.to_le_bytes());
        }
        m.extend(id.to_le_bytes());
        for v in quat(cam).into_iter().chain(cam.t.iter().copied()) {
            m.extend(v.to_le_bytes());
        }
        m.extend(id.to_le_bytes());
        m.extend(cam.name.as_bytes());
        m.push(0);
        m.extend(0u64.to_le_bytes());
    }
    (c, m)
}

/// The temple in a folder per format.
struct Folders {
    _tmp: tempfile::TempDir,
    par: PathBuf,
    text: PathBuf,
    binary: PathBuf,
    matrices: PathBuf,
}

fn folders() -> Folders {
    let cams = par_cams();
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let par = root.join("par");
    photos_into(&par, &cams);
    std::fs::copy(
        temple().join("templeSR_par.txt"),
        par.join("templeSR_par.txt"),
    )
    .unwrap();
    // COLMAP text in sparse/0/, photos in images/.
    let text = root.join("text");
    photos_into(&text.join("images"), &cams);
    std::fs::create_dir_all(text.join("sparse/0")).unwrap();
    let (c, m) = colmap_text(&cams, 640, 480);
    std::fs::write(text.join("sparse/0/cameras.txt"), c).unwrap();
    std::fs::write(text.join("sparse/0/images.txt"), m).unwrap();
    // COLMAP binary in the folder itself.
    let binary = root.join("binary");
    photos_into(&binary.join("images"), &cams);
    let (c, m) = colmap_binary(&cams, 640, 480);
    std::fs::write(binary.join("cameras.bin"), c).unwrap();
    std::fs::write(binary.join("images.bin"), m).unwrap();
    // Projection matrices in cameras/, photos beside it, P scaled by -2 (any scale and sign).
    let matrices = root.join("matrices");
    photos_into(&matrices, &cams);
    std::fs::create_dir_all(matrices.join("cameras")).unwrap();
    for c in &cams {
        let p = c.projection() * -2.0;
        let mut s = String::from("CONTOUR\n");
        for r in 0..3 {
            let row: Vec<String> = (0..4).map(|k| format!("{:?}", p[(r, k)])).collect();
            s += &row.join(" ");
            s.push('\n');
        }
        let stem = c.name.trim_end_matches(".png");
        std::fs::write(matrices.join("cameras").join(format!("{stem}.txt")), s).unwrap();
    }
    Folders {
        _tmp: tmp,
        par,
        text,
        binary,
        matrices,
    }
}

fn opt() -> DataOptions {
    DataOptions {
        scale: 0.5,
        ..Default::default()
    }
}

#[test]
fn every_format_gives_the_same_model() {
    let f = folders();
    let load = |d: &Path| Dataset::load(d, &opt()).unwrap();
    let par = load(&f.par);
    assert_eq!(par.format, CameraFormat::Par);
    assert_eq!(par.cams.len(), 16);
    // The visual and photo hulls, which every camera's projection decides; the stereo carving
    // reads the same cameras and would take three quarters of the test's time.
    let params = ModelParams {
        grid: 64,
        stereo: false,
        ..Default::default()
    };
    let bounds = par.volume(None).unwrap();
    let (model, _) = build_summarised(
        &par.cams,
        &par.images,
        &par.masks,
        bounds,
        &params,
        &mut |_, _, _| {},
    )
    .unwrap();
    assert!(model.grid.count() > 1000);
    for (dir, format) in [
        (&f.text, CameraFormat::ColmapText),
        (&f.binary, CameraFormat::ColmapBinary),
        (&f.matrices, CameraFormat::Matrices),
    ] {
        let d = load(dir);
        assert_eq!(d.format, format);
        assert_eq!(d.cams.len(), par.cams.len());
        for (a, b) in d.cams.iter().zip(&par.cams) {
            assert_eq!(a.name, b.name, "{format}");
            let (pa, pb) = (a.projection(), b.projection());
            let rel = (pa - pb).abs().max() / pb.abs().max();
            assert!(rel < 1e-12, "{format} {}: P differs by {rel:e}", a.name);
        }
        assert!(d.images == par.images, "{format}: photos differ");
        assert!(d.masks == par.masks, "{format}: silhouettes differ");
        let b = d.volume(None).unwrap();
        assert!((b.min - bounds.min).norm() < 1e-9 && (b.max - bounds.max).norm() < 1e-9);
        // Same bounds given, so any difference is the cameras'.
        let (m, _) = build_summarised(
            &d.cams,
            &d.images,
            &d.masks,
            bounds,
            &params,
            &mut |_, _, _| {},
        )
        .unwrap();
        assert_eq!(
            m.grid.occupied(),
            model.grid.occupied(),
            "{format}: voxel sets differ"
        );
        assert_eq!(m.surface, model.surface, "{format}: surface colours differ");
    }
}

fn err(d: &Path) -> String {
    let e: DataError = Dataset::load(d, &opt()).unwrap_err();
    let s = e.to_string();
    assert!(!s.contains('\n'), "one line: {s}");
    s
}

#[test]
fn bad_camera_files_are_one_line_naming_file_and_fault() {
    let f = folders();
    let images = f.text.join("sparse/0/images.txt");
    let good = std::fs::read_to_string(&images).unwrap();
    // Truncated between images: the header's count says so.
    let cut: String = good.lines().take(12).collect::<Vec<_>>().join("\n");
    std::fs::write(&images, &cut).unwrap();
    let e = err(&f.text);
    assert!(
        e.contains("images.txt") && e.contains("header says 16 images, found 5"),
        "{e}"
    );
    // Truncated inside an image line.
    std::fs::write(&images, &good[..good.len() - 30]).unwrap();
    let e = err(&f.text);
    assert!(e.contains("images.txt: line 33: expected IMAGE_ID"), "{e}");
    // NaN in a pose.
    let first = good.lines().nth(2).unwrap();
    let tx = first.split_whitespace().nth(5).unwrap();
    std::fs::write(&images, good.replacen(tx, "NaN", 1)).unwrap();
    let e = err(&f.text);
    assert!(e.contains("line 3: TX is not finite"), "{e}");
    std::fs::write(&images, &good).unwrap();
    // Unknown camera model.
    let cameras = f.text.join("sparse/0/cameras.txt");
    let c = std::fs::read_to_string(&cameras).unwrap();
    std::fs::write(&cameras, c.replacen("PINHOLE", "THIN_PRISM_FISHEYE", 1)).unwrap();
    let e = err(&f.text);
    assert!(
        e.contains("cameras.txt: line 3: camera model \"THIN_PRISM_FISHEYE\" is not supported"),
        "{e}"
    );
    std::fs::write(&cameras, &c).unwrap();
    // A photo the model names is missing.
    std::fs::remove_file(f.text.join("images/templeSR0003.png")).unwrap();
    let e = err(&f.text);
    assert!(
        e.contains("\"templeSR0003.png\"") && e.contains("missing"),
        "{e}"
    );
    // Two formats in one folder.
    std::fs::copy(
        temple().join("templeSR_par.txt"),
        f.binary.join("templeSR_par.txt"),
    )
    .unwrap();
    let e = err(&f.binary);
    assert!(e.contains("cameras in more than one place"), "{e}");
    // A truncated binary model names the byte.
    std::fs::remove_file(f.binary.join("templeSR_par.txt")).unwrap();
    let bin = std::fs::read(f.binary.join("images.bin")).unwrap();
    std::fs::write(f.binary.join("images.bin"), &bin[..bin.len() - 5]).unwrap();
    let e = err(&f.binary);
    assert!(
        e.contains("images.bin: byte") && e.contains("file ends inside"),
        "{e}"
    );
    // A matrix that is no camera, and one that is not 12 numbers.
    let m = f.matrices.join("cameras/templeSR0002.txt");
    std::fs::write(&m, "1 2 3 0\n2 4 6 0\n0 0 0 1\n").unwrap();
    let e = err(&f.matrices);
    assert!(
        e.contains("templeSR0002.txt") && e.contains("singular"),
        "{e}"
    );
    std::fs::write(&m, "1 0 0 0\n0 1 0 0\n0 0 1\n").unwrap();
    let e = err(&f.matrices);
    assert!(e.contains("templeSR0002.txt: line 3: 11 numbers"), "{e}");
}

#[test]
fn a_pose_read_the_wrong_way_round_is_refused_naming_the_photo() {
    // camera-to-world written where COLMAP wants world-to-camera: the photo's camera then has
    // the temple behind it.
    let f = folders();
    let images = f.text.join("sparse/0/images.txt");
    let cams = par_cams();
    let mut flipped = cams.clone();
    let c = &cams[4];
    let rt = c.r.transpose();
    flipped[4] = Camera::new(c.name.clone(), c.k, rt, -(rt * c.t)).unwrap();
    let (_, m) = colmap_text(&flipped, 640, 480);
    std::fs::write(&images, m).unwrap();
    let d = Dataset::load(&f.text, &opt()).unwrap();
    // The temple's tight box (its README).
    let tight = Aabb::new(
        Vector3::new(-0.073568, 0.021728, -0.012445),
        Vector3::new(0.028855, 0.181892, 0.062736),
    );
    let e = d.volume(Some(tight)).unwrap_err().to_string();
    assert!(
        e.contains("templeSR0005.png") && e.contains("behind the camera"),
        "{e}"
    );
    // The unflipped cameras have it in front.
    assert!(Dataset::load(&f.par, &opt())
        .unwrap()
        .volume(Some(tight))
        .is_ok());
}
