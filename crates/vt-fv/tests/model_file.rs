//! The model file (`vt fv hull`'s model.vtfv) and steady orbits, on the real data in testdata/:
//! a model written and read back renders the same bytes as the one built in process; bad files
//! and files from other data are refused naming the file; orbits have no frame-to-frame pop.

use std::path::PathBuf;
use std::sync::OnceLock;
use std::time::Instant;

use vt_fv::camera::Ring;
use vt_fv::dataset::{
    read_model, write_model, BuildSummary, DataOptions, Dataset, ModelParams, MODEL_FILE,
};
use vt_fv::orbit::orbit;
use vt_fv::photo::VoxelModel;
use vt_fv::pipeline::{novel_view_in, ViewParams};
use vt_fv::texture::model_centre;

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata")
        .join(name)
}

fn load(name: &str, scale: f64) -> Dataset {
    let opt = DataOptions {
        scale,
        ..Default::default()
    };
    Dataset::load(&data(name), &opt).unwrap()
}

fn params() -> ModelParams {
    ModelParams {
        grid: 64,
        ..Default::default()
    }
}

/// The temple at half size with its model from every view ([`params`]), built once for the
/// tests that read it, and the seconds the build took.
struct Built {
    data: Dataset,
    model: VoxelModel,
    summary: BuildSummary,
    secs: f64,
}

fn temple() -> &'static Built {
    static BUILT: OnceLock<Built> = OnceLock::new();
    BUILT.get_or_init(|| {
        let data = load("templeSparseRing", 0.5);
        let t = Instant::now();
        let (model, summary) = data
            .build_without(None, &params(), &mut |_, _, _| {})
            .unwrap();
        Built {
            data,
            model,
            summary,
            secs: t.elapsed().as_secs_f64(),
        }
    })
}

#[test]
fn model_read_back_renders_the_same_bytes_and_faster() {
    let Built {
        data: d,
        model,
        summary: s,
        secs: build,
    } = temple();
    let m = params();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join(MODEL_FILE);
    write_model(&file, model, &d.model_header(None, &m, s)).unwrap();
    let t = Instant::now();
    let (back, header) = read_model(&file, d).unwrap();
    let read = t.elapsed().as_secs_f64();
    assert_eq!(back.grid, model.grid);
    assert_eq!(back.surface, model.surface);
    assert_eq!(header.views.len(), 16);
    // The photos' depth maps travel with the model, bit for bit (NaN where there is none).
    assert_eq!(back.depths.len(), 16);
    for (a, b) in model.depths.iter().zip(&back.depths) {
        assert_eq!((a.w, a.h, a.step), (b.w, b.h, b.step));
        let bits = |m: &vt_fv::stereo::DepthMap| -> Vec<u32> {
            m.depth
                .iter()
                .map(|d| if d.is_nan() { u32::MAX } else { d.to_bits() })
                .collect()
        };
        assert_eq!(bits(a), bits(b));
    }
    assert!(back.depths.iter().map(|m| m.count()).sum::<usize>() > 1000);
    let ring = Ring::fit(&d.cams).unwrap();
    let (w, h) = d.size();
    // Both with and without the depth clip, which reads the depth maps.
    for (view, angle) in [
        (ViewParams::default(), 0.0),
        (ViewParams::default(), 50.0),
        (
            ViewParams {
                depth_clip: Some(Default::default()),
                ..Default::default()
            },
            200.0,
        ),
    ] {
        let view = &view;
        let cam = ring.camera(angle, &model_centre(model)).unwrap();
        let a = novel_view_in(model, &d.cams, &d.images, Some(&d.masks), &cam, w, h, view).unwrap();
        let b = novel_view_in(&back, &d.cams, &d.images, Some(&d.masks), &cam, w, h, view).unwrap();
        assert!(a.rough.coverage.count_ones() > 1000);
        assert_eq!(a.guided.as_raw(), b.guided.as_raw(), "angle {angle}");
    }
    let bytes = std::fs::metadata(&file).unwrap().len();
    println!(
        "temple at half size, grid 64: model built in {build:.2} s, read in {read:.3} s ({bytes} bytes, {} surface voxels)",
        model.surface.len()
    );
}

#[test]
fn bad_model_files_are_refused_naming_the_file() {
    let Built {
        data: d,
        model,
        summary: s,
        ..
    } = temple();
    let m = params();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join(MODEL_FILE);
    write_model(&file, model, &d.model_header(None, &m, s)).unwrap();
    let good = std::fs::read(&file).unwrap();
    let bad = dir.path().join("bad.vtfv");
    let refused = |bytes: &[u8]| {
        std::fs::write(&bad, bytes).unwrap();
        let e = read_model(&bad, d).unwrap_err().to_string();
        assert!(e.contains("bad.vtfv") && !e.contains('\n'), "{e}");
        e
    };
    let e = refused(&good[..good.len() / 2]);
    assert!(e.contains("checksum"), "{e}");
    let e = refused(&good[..10]);
    assert!(e.contains("cut short"), "{e}");
    let mut v3 = good.clone();
    v3[8] = 3;
    let e = refused(&v3);
    assert!(e.contains("version 3"), "{e}");
    let e = refused(b"ply\nformat ascii 1.0\n");
    assert!(e.contains("not a vt fv model file"), "{e}");
    let mut flipped = good.clone();
    let k = flipped.len() - 20;
    flipped[k] ^= 0x10;
    let e = refused(&flipped);
    assert!(e.contains("checksum"), "{e}");
    // Other data: other silhouettes, another scale, another folder.
    let other = Dataset::load(
        &data("templeSparseRing"),
        &DataOptions {
            scale: 0.5,
            threshold: 0.3,
            ..Default::default()
        },
    )
    .unwrap();
    let e = read_model(&file, &other).unwrap_err().to_string();
    assert!(
        e.contains("model.vtfv") && e.contains("silhouette differs"),
        "{e}"
    );
    let e = read_model(&file, &load("templeSparseRing", 0.25))
        .unwrap_err()
        .to_string();
    assert!(e.contains("model.vtfv") && e.contains("320x240"), "{e}");
    let e = read_model(&file, &load("kettle", 1.0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("model.vtfv") && e.contains("16 views"), "{e}");
}

/// A whole turn of `frames` textured views of `d` from `model`; the largest frame-to-frame
/// step over the median.
fn orbit_ratio(name: &str, d: &Dataset, model: &VoxelModel, frames: usize) -> f64 {
    let ring = Ring::fit(&d.cams).unwrap();
    let t = Instant::now();
    let steady = orbit::<vt_fv::Error>(
        model,
        &d.cams,
        &d.images,
        Some(&d.masks),
        &ring,
        &model_centre(model),
        frames,
        d.size(),
        &ViewParams::default(),
        &mut |_, _, v| {
            assert!(v.rough.coverage.count_ones() > 100);
            Ok(())
        },
    )
    .unwrap();
    assert_eq!(steady.steps.len(), frames);
    println!(
        "{name}: {frames} frames in {:.2} s; {steady}",
        t.elapsed().as_secs_f64()
    );
    steady.ratio()
}

#[test]
fn orbits_are_steady() {
    // Before the ring kept the photos' roll and the weights faded, the temple's orbit turned
    // the picture half round between two frames (ratio 3.6 at full size).
    let b = temple();
    let r = orbit_ratio("templeSparseRing", &b.data, &b.model, 36);
    assert!(r > 0.0 && r <= 2.0, "temple: largest/median step {r:.2}");
    let kettle = load("kettle", 1.0);
    let (model, _) = kettle
        .build_without(None, &params(), &mut |_, _, _| {})
        .unwrap();
    let r = orbit_ratio("kettle", &kettle, &model, 36);
    assert!(r > 0.0 && r <= 2.0, "kettle: largest/median step {r:.2}");
}
