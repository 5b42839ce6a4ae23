//! Fuzzing vt-io's parsers on stable Rust with proptest: the points file, scene.json, the
//! moving-object store and the image front door, each with random input and with
//! structure-aware mutations of a valid file. The property is always the same: no panic, and
//! what is accepted is usable (validated invariants hold, every frame decodes).
//!
//! Cases per parser: 10,000 in the test command; `VT_FUZZ_CASES=1000000 cargo test --release -p
//! vt-io --test fuzz` is the long run (its last result is in crates/vt-io/README.md).

use std::path::Path;

use image::RgbImage;
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use vt_io::objects::{ObjectStore, ObjectWriter};
use vt_io::scene::SceneFile;

fn cases() -> u32 {
    std::env::var("VT_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000)
}

fn runner() -> TestRunner {
    TestRunner::new(Config {
        cases: cases(),
        failure_persistence: None,
        ..Config::default()
    })
}

/// A mutation of a byte string: flip, set, insert, delete, truncate, duplicate a slice, or write
/// an extreme little-endian integer somewhere.
#[derive(Debug, Clone)]
enum Mutation {
    Flip(usize, u8),
    Set(usize, u8),
    Insert(usize, Vec<u8>),
    Delete(usize, usize),
    Truncate(usize),
    Duplicate(usize, usize),
    Extreme(usize, u64, usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let extreme = prop_oneof![
        Just(0u64),
        Just(1),
        Just(u32::MAX as u64),
        Just(u64::MAX),
        Just(1 << 31),
        Just(16384),
        Just(16385),
        any::<u64>()
    ];
    prop_oneof![
        (any::<usize>(), 1u8..=255).prop_map(|(i, b)| Mutation::Flip(i, b)),
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Mutation::Set(i, b)),
        (any::<usize>(), prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(i, v)| Mutation::Insert(i, v)),
        (any::<usize>(), 1usize..64).prop_map(|(i, n)| Mutation::Delete(i, n)),
        any::<usize>().prop_map(Mutation::Truncate),
        (any::<usize>(), 1usize..64).prop_map(|(i, n)| Mutation::Duplicate(i, n)),
        (any::<usize>(), extreme, prop_oneof![Just(4usize), Just(8)])
            .prop_map(|(i, v, w)| Mutation::Extreme(i, v, w)),
    ]
}

fn apply(data: &mut Vec<u8>, m: &Mutation) {
    let n = data.len().max(1);
    match m {
        Mutation::Flip(i, b) => {
            if let Some(x) = data.get_mut(i % n) {
                *x ^= b;
            }
        }
        Mutation::Set(i, b) => {
            if let Some(x) = data.get_mut(i % n) {
                *x = *b;
            }
        }
        Mutation::Insert(i, v) => {
            let at = i % (data.len() + 1);
            data.splice(at..at, v.iter().copied());
        }
        Mutation::Delete(i, k) => {
            let at = i % n;
            let end = (at + k).min(data.len());
            if at < end {
                data.drain(at..end);
            }
        }
        Mutation::Truncate(i) => data.truncate(i % n),
        Mutation::Duplicate(i, k) => {
            let at = i % n;
            let end = (at + k).min(data.len());
            if at < end {
                let part: Vec<u8> = data[at..end].to_vec();
                data.splice(at..at, part);
            }
        }
        Mutation::Extreme(i, v, w) => {
            let at = i % n;
            let bytes = v.to_le_bytes();
            for k in 0..*w {
                if let Some(x) = data.get_mut(at + k) {
                    *x = bytes[k];
                }
            }
        }
    }
}

fn mutated(base: Vec<u8>) -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(mutation(), 1..6).prop_map(move |ms| {
        let mut d = base.clone();
        for m in &ms {
            apply(&mut d, m);
        }
        d
    })
}

/// Random bytes, or a mutation of `base`.
fn input(base: Vec<u8>) -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        1 => prop::collection::vec(any::<u8>(), 0..256),
        4 => mutated(base),
    ]
}

// ---- points file ----

/// Tokens a points file may contain, good and bad.
fn token() -> impl Strategy<Value = String> {
    prop_oneof![
        (-1e4f64..1e4).prop_map(|x| format!("{x}")),
        any::<f64>().prop_map(|x| format!("{x}")),
        Just("nan".to_string()),
        Just("inf".to_string()),
        Just("-0".to_string()),
        Just("1e309".to_string()),
        Just("#".to_string()),
        Just(",".to_string()),
        "[ -~]{0,12}",
        "\\PC{0,4}",
    ]
}

fn points_text() -> impl Strategy<Value = String> {
    let line = prop::collection::vec(token(), 0..14).prop_map(|t| t.join(" "));
    prop_oneof![
        prop::collection::vec(line, 0..6).prop_map(|l| l.join("\n")),
        prop::collection::vec(any::<u8>(), 0..200)
            .prop_map(|b| String::from_utf8_lossy(&b).to_string()),
        mutated(b"# vt points\n1 2 3 4 5 6 7 8\n2 3 4 5 6 7 8 9\n".to_vec())
            .prop_map(|b| String::from_utf8_lossy(&b).to_string()),
    ]
}

#[test]
fn fuzz_points_file() {
    runner()
        .run(&points_text(), |text| {
            if let Ok(views) = vt_io::points::parse_points(&text, Path::new("p.txt")) {
                prop_assert!(!views.is_empty());
                let k = views[0].len();
                prop_assert!(k >= 4);
                for v in &views {
                    prop_assert_eq!(v.len(), k);
                    prop_assert!(v.iter().all(|p| p.x.is_finite() && p.y.is_finite()));
                }
            }
            Ok(())
        })
        .unwrap();
}

// ---- scene.json ----

fn valid_scene_json() -> serde_json::Value {
    let frames = 6;
    let view = |p: usize| {
        let next: Vec<Option<usize>> = (0..frames).map(|s| (p == 0).then_some(s % 3)).collect();
        let prev: Vec<Option<usize>> = (0..frames).map(|s| (p == 1).then_some(s % 3)).collect();
        let h = [[1.0, 0.0, 2.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let hinv = [[1.0, 0.0, -2.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        serde_json::json!({
            "name": format!("view{p}"),
            "frames": frames,
            "points": [[1.0, 1.0], [10.0, 1.0], [10.0, 10.0], [1.0, 10.0]],
            "background": format!("background_00{p}.png"),
            "objects": format!("objects_00{p}.bin"),
            "moving_fraction": 0.1,
            "loop": {"start": 0, "end": 4, "cost": 3},
            "to_next": if p == 0 { serde_json::json!({"homography": h, "rms": 0.1}) } else { serde_json::Value::Null },
            "to_prev": if p == 1 { serde_json::json!({"homography": hinv, "rms": 0.1}) } else { serde_json::Value::Null },
            "transitions": {"next": next, "prev": prev},
        })
    };
    serde_json::json!({
        "format": "vt-scene",
        "version": 1,
        "created_by": "fuzz",
        "width": 16,
        "height": 12,
        "params": serde_json::to_value(vt_core::analysis::AnalyzeParams::default()).unwrap(),
        "model": null,
        "views": [view(0), view(1)],
    })
}

/// Replaces one value somewhere in a JSON tree (chosen by `pick`) with `with`.
fn replace_value(v: &mut serde_json::Value, pick: &mut u64, with: &serde_json::Value) -> bool {
    if *pick == 0 {
        *v = with.clone();
        return true;
    }
    *pick -= 1;
    match v {
        serde_json::Value::Array(a) => a.iter_mut().any(|x| replace_value(x, pick, with)),
        serde_json::Value::Object(o) => o.values_mut().any(|x| replace_value(x, pick, with)),
        _ => false,
    }
}

fn json_value() -> impl Strategy<Value = serde_json::Value> {
    prop_oneof![
        Just(serde_json::json!(null)),
        any::<i64>().prop_map(|x| serde_json::json!(x)),
        any::<u64>().prop_map(|x| serde_json::json!(x)),
        Just(serde_json::json!(u32::MAX)),
        Just(serde_json::json!(100000000u64)),
        (-1e6f64..1e6).prop_map(|x| serde_json::json!(x)),
        Just(serde_json::json!(1e308)),
        Just(serde_json::json!("../../etc/passwd")),
        Just(serde_json::json!("/etc/passwd")),
        "[ -~]{0,8}".prop_map(|s| serde_json::json!(s)),
        Just(serde_json::json!([])),
        Just(serde_json::json!({})),
        Just(serde_json::json!([
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0]
        ])),
    ]
}

#[test]
fn fuzz_scene_json() {
    let base = valid_scene_json();
    let text = serde_json::to_string_pretty(&base).unwrap();
    SceneFile::parse(&text, Path::new("scene.json")).expect("the base scene is valid");
    let structured = prop::collection::vec((0u64..200, json_value()), 1..4).prop_map({
        let base = base.clone();
        move |edits| {
            let mut v = base.clone();
            for (mut pick, with) in edits {
                replace_value(&mut v, &mut pick, &with);
            }
            serde_json::to_vec(&v).unwrap()
        }
    });
    let strategy = prop_oneof![
        2 => structured,
        1 => input(text.into_bytes()),
    ];
    runner()
        .run(&strategy, |bytes| {
            let text = String::from_utf8_lossy(&bytes);
            if let Ok(scene) = SceneFile::parse(&text, Path::new("scene.json")) {
                // Accepted scenes are usable: names stay inside the folder, links are valid.
                for v in &scene.views {
                    prop_assert!(vt_io::scene::is_plain_file_name(&v.background));
                    prop_assert!(vt_io::scene::is_plain_file_name(&v.objects));
                    prop_assert!(v.loop_.start < v.loop_.end && v.loop_.end < v.frames);
                    for l in v.to_next.iter().chain(v.to_prev.iter()) {
                        prop_assert!(l.homography().is_ok());
                    }
                }
            }
            Ok(())
        })
        .unwrap();
}

// ---- object store ----

fn valid_store(quality: vt_io::objects::StoreQuality) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("objects_000.bin");
    let (w, h) = (13, 9);
    let mut writer = ObjectWriter::create_with(&path, w, h, quality).unwrap();
    for f in 0..4u32 {
        let mask = vt_core::Mask::from_fn(w, h, |x, y| (x + y + f) % 3 == 0 && x > f);
        let raw = RgbImage::from_fn(w, h, |x, y| image::Rgb([x as u8, y as u8, f as u8]));
        writer.push(&mask, &raw).unwrap();
    }
    writer
        .push(&vt_core::Mask::new(w, h), &RgbImage::new(w, h))
        .unwrap();
    writer.finish().unwrap();
    std::fs::read(&path).unwrap()
}

#[test]
fn fuzz_object_store() {
    for quality in [
        vt_io::objects::StoreQuality::Lossless,
        vt_io::objects::StoreQuality::default(),
    ] {
        fuzz_one_store(quality);
    }
}

fn fuzz_one_store(quality: vt_io::objects::StoreQuality) {
    let base = valid_store(quality);
    let ok = ObjectStore::from_bytes(base.clone(), Path::new("o.bin")).expect("valid store");
    assert_eq!(ok.len(), 5);
    runner()
        .run(&input(base), |bytes| {
            if let Ok(store) = ObjectStore::from_bytes(bytes, Path::new("o.bin")) {
                // Everything accepted decodes, frame by frame, without a panic.
                let (w, h) = store.size();
                let mut patch = vt_core::render::ObjectPatch::default();
                for i in 0..store.len() {
                    let m = store.mask(i);
                    prop_assert_eq!((m.width(), m.height()), (w, h));
                    // A damaged access unit is an error, never a panic.
                    let _ = store.decode_into(i, &mut patch);
                }
            }
            Ok(())
        })
        .unwrap();
}

// ---- image front door ----

fn encoded(format: image::ImageFormat) -> Vec<u8> {
    let img = RgbImage::from_fn(11, 7, |x, y| image::Rgb([x as u8 * 20, y as u8 * 30, 128]));
    let mut bytes = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut bytes), format)
        .unwrap();
    bytes
}

#[test]
fn fuzz_image_front_door() {
    let png = encoded(image::ImageFormat::Png);
    let jpg = encoded(image::ImageFormat::Jpeg);
    let strategy = prop_oneof![input(png), input(jpg)];
    runner()
        .run(&strategy, |bytes| {
            if let Ok(img) = vt_io::frames::decode_rgb(&bytes, Path::new("f.png")) {
                let (w, h) = img.dimensions();
                prop_assert!(w >= 1 && h >= 1);
                prop_assert!(
                    w <= vt_io::limits::MAX_IMAGE_SIDE && h <= vt_io::limits::MAX_IMAGE_SIDE
                );
            }
            Ok(())
        })
        .unwrap();
}
