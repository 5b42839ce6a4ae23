//! The two camera paths agree: vt-synth's own pinhole maths (which makes System B's synthetic
//! truth) and vt-fv's `Camera` (which the pipeline uses) project, back-project and place the
//! centre alike on the temple's real cameras, and vt-fv reads the par file vt-synth writes.
//! The synthetic truth checks vt-fv only because the two are written independently; this test
//! checks they mean the same thing.

use std::path::PathBuf;

use nalgebra::Vector3;
use vt_fv::camera::parse_par;
use vt_synth::object::{format_par, ring_camera, PinholeCamera, SceneParams};

fn temple_cameras() -> Vec<vt_fv::Camera> {
    let par = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata/templeSparseRing/templeSR_par.txt");
    parse_par(&std::fs::read_to_string(par).unwrap()).unwrap()
}

/// World points around the temple (its bounding box, from the data set's README, and beyond).
fn points() -> Vec<Vector3<f64>> {
    let (lo, hi) = (
        Vector3::new(-0.073568, 0.021728, -0.012445),
        Vector3::new(0.028494, 0.181823, 0.062607),
    );
    (0..125)
        .map(|i| {
            let f = Vector3::new((i % 5) as f64, (i / 5 % 5) as f64, (i / 25) as f64) / 4.0;
            lo + (hi - lo).component_mul(&(f * 1.5 - Vector3::repeat(0.25)))
        })
        .collect()
}

#[test]
fn synth_camera_maths_agree_with_vt_fv_on_the_temple_cameras() {
    let cams = temple_cameras();
    assert_eq!(cams.len(), 16);
    for fv in &cams {
        let synth = PinholeCamera::new(fv.name.clone(), fv.k, fv.r, fv.t).unwrap();
        assert!(
            (synth.centre() - fv.centre()).norm() < 1e-12,
            "{}: centres differ",
            fv.name
        );
        for x in points() {
            let (u, v) = synth
                .project(&x)
                .expect("the temple is in front of every camera");
            let (fu, fv_, _) = fv.project(&x).unwrap();
            assert!(
                (u - fu).abs() < 1e-9 && (v - fv_).abs() < 1e-9,
                "{}: {x:?} projects to ({u}, {v}) by vt-synth, ({fu}, {fv_}) by vt-fv",
                fv.name
            );
        }
        for (u, v) in [(0.0, 0.0), (639.0, 479.0), (302.32, 246.87), (17.5, 400.25)] {
            let (a, b) = (synth.ray(u, v), fv.ray(u, v));
            assert!(
                (a - b).norm() < 1e-12,
                "{}: rays through ({u}, {v}) differ: {a:?} vs {b:?}",
                fv.name
            );
        }
    }
}

#[test]
fn vt_fv_reads_the_par_file_vt_synth_writes() {
    let p = SceneParams::default();
    let synth: Vec<PinholeCamera> = [0.0, 45.0, 190.0]
        .iter()
        .map(|&a| ring_camera(&p, a).unwrap())
        .collect();
    let read = parse_par(&format_par(&synth)).unwrap();
    assert_eq!(read.len(), synth.len());
    for (s, f) in synth.iter().zip(&read) {
        assert_eq!(s.name, f.name);
        assert_eq!((s.k, s.r, s.t), (f.k, f.r, f.t), "{}", s.name);
        // And vt-fv's look-at builds the same camera from the same centre and target.
        let look =
            vt_fv::Camera::look_at("", s.k, s.centre(), Vector3::zeros(), -Vector3::z()).unwrap();
        assert!((look.r - s.r).norm() < 1e-12 && (look.t - s.t).norm() < 1e-12);
    }
}
