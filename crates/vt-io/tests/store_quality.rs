//! The object store's default quality on real footage: `testdata/tree.avi` (a real tree in wind,
//! decoded by ffmpeg) stored whole-frame at the default quality and read back at random, against
//! the decoded frames themselves. Skipped (printed) when ffmpeg is not installed.

use std::path::Path;

use image::RgbImage;
use vt_core::Mask;
use vt_io::objects::{H264Encoder, ObjectStore, ObjectWriter, StoreQuality};

fn tree_frames(n: usize) -> Option<Vec<RgbImage>> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/tree.avi");
    let mut src = vt_io::frames::ViewSource::open(&path).ok()?;
    let mut frames = Vec::new();
    src.as_source()
        .for_each_frame(&mut |_, f| {
            if frames.len() < n {
                frames.push(f.clone());
            }
            Ok(())
        })
        .ok()?;
    Some(frames)
}

#[test]
fn default_quality_keeps_real_footage_above_40_db() {
    let Some(frames) = tree_frames(96) else {
        println!("skipped: ffmpeg could not decode testdata/tree.avi");
        return;
    };
    assert!(frames.len() >= 64, "{} frames", frames.len());
    let (w, h) = frames[0].dimensions();
    // The mask of a tree scene: the tree's region, with a box that moves a little.
    let masks: Vec<Mask> = (0..frames.len())
        .map(|f| Mask::from_fn(w, h, |x, y| x >= (f % 7) as u32 && y > h / 8))
        .collect();
    let dir = tempfile::tempdir().unwrap();
    // Lossless, then the default quality from each encoder (x264 only where ffmpeg has it).
    let mut runs = vec![
        (StoreQuality::Lossless, H264Encoder::Auto),
        (StoreQuality::default(), H264Encoder::OpenH264),
    ];
    if ObjectWriter::x264_available() {
        runs.push((StoreQuality::default(), H264Encoder::X264));
    }
    let sizes: Vec<(StoreQuality, u64, f64)> = runs
        .into_iter()
        .map(|(quality, encoder)| {
            let path = dir.path().join(format!("o_{quality}_{encoder:?}.bin"));
            let mut writer =
                ObjectWriter::create_with_encoder(&path, w, h, quality, encoder).unwrap();
            for (m, f) in masks.iter().zip(&frames) {
                writer.push(m, f).unwrap();
            }
            writer.finish().unwrap();
            let store = ObjectStore::load(&path).unwrap();
            let mut patch = vt_core::render::ObjectPatch::default();
            let (mut se, mut count) = (0f64, 0u64);
            // A player's order: a stretch, a jump back (a loop wrap), a jump ahead.
            let n = frames.len();
            let order: Vec<usize> = (10..60).chain(3..40).chain(62..n).collect();
            for &i in &order {
                store.decode_into(i, &mut patch).unwrap();
                for k in 0..(patch.width * patch.height) as usize {
                    let (x, y) = (
                        patch.x0 + k as u32 % patch.width,
                        patch.y0 + k as u32 / patch.width,
                    );
                    assert_eq!(patch.mask[k] == 1, masks[i].get(x, y), "frame {i} mask");
                    if patch.mask[k] == 1 {
                        let want = frames[i].get_pixel(x, y).0;
                        for c in 0..3 {
                            se += (patch.rgb[3 * k + c] as f64 - want[c] as f64).powi(2);
                        }
                        count += 3;
                    }
                }
            }
            let psnr = 10.0 * (255.0f64 * 255.0 / (se / count as f64).max(1e-12)).log10();
            (quality, std::fs::metadata(&path).unwrap().len(), psnr)
        })
        .collect();
    if std::env::var_os("VT_TEST_VERBOSE").is_some() {
        println!("{sizes:?}");
    }
    assert!(sizes[0].2 > 90.0, "lossless: {} dB", sizes[0].2);
    for s in &sizes[1..] {
        assert!(s.2 >= 40.0, "default: {:.2} dB", s.2);
        assert!(
            s.1 * 4 < sizes[0].1,
            "default {} bytes, lossless {}",
            s.1,
            sizes[0].1
        );
    }
}

/// Issue #34: the default quality target spends bits where the footage has detail. Smooth
/// footage (tree.avi upscaled 2x, as an HD video of a low-resolution source is) gets a coarser
/// quantiser than the original and is smaller than the finest quantiser makes it, and both
/// keep 40 dB.
#[test]
fn the_quality_target_follows_the_footage() {
    let Some(frames) = tree_frames(24) else {
        println!("skipped: ffmpeg could not decode testdata/tree.avi");
        return;
    };
    let (w, h) = frames[0].dimensions();
    let smooth: Vec<RgbImage> = frames
        .iter()
        .map(|f| image::imageops::resize(f, 2 * w, 2 * h, image::imageops::FilterType::CatmullRom))
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let store = |frames: &[RgbImage], quality: StoreQuality, name: &str| {
        let (w, h) = frames[0].dimensions();
        let mask = Mask::from_fn(w, h, |_, y| y > h / 8);
        let path = dir.path().join(name);
        let mut writer = ObjectWriter::create_with(&path, w, h, quality).unwrap();
        for f in frames {
            writer.push(&mask, f).unwrap();
        }
        writer.finish().unwrap();
        let s = ObjectStore::load(&path).unwrap();
        let mut patch = vt_core::render::ObjectPatch::default();
        let (mut se, mut n) = (0f64, 0u64);
        for (i, f) in frames.iter().enumerate() {
            s.decode_into(i, &mut patch).unwrap();
            for k in 0..(patch.width * patch.height) as usize {
                if patch.mask[k] == 1 {
                    let (x, y) = (
                        patch.x0 + k as u32 % patch.width,
                        patch.y0 + k as u32 / patch.width,
                    );
                    let want = f.get_pixel(x, y).0;
                    for c in 0..3 {
                        se += (patch.rgb[3 * k + c] as f64 - want[c] as f64).powi(2);
                    }
                    n += 3;
                }
            }
        }
        let psnr = 10.0 * (255.0f64 * 255.0 / (se / n as f64).max(1e-12)).log10();
        let StoreQuality::H264 { qp } = s.quality() else {
            panic!("{name}: {:?}", s.quality());
        };
        (qp, std::fs::metadata(&path).unwrap().len(), psnr)
    };
    let (qp_detail, _, db_detail) = store(&frames, StoreQuality::default(), "detail.bin");
    let (qp_smooth, bytes_smooth, db_smooth) =
        store(&smooth, StoreQuality::default(), "smooth.bin");
    let (_, bytes_finest, _) = store(&smooth, StoreQuality::H264 { qp: 12 }, "finest.bin");
    if std::env::var_os("VT_TEST_VERBOSE").is_some() {
        println!(
            "detail: qp {qp_detail}, {db_detail:.2} dB; smooth: qp {qp_smooth}, {db_smooth:.2} dB, {bytes_smooth} bytes against {bytes_finest} at qp 12"
        );
    }
    assert!(
        db_detail >= 40.0 && db_smooth >= 40.0,
        "{db_detail} {db_smooth}"
    );
    assert!(
        qp_smooth > qp_detail,
        "smooth qp {qp_smooth}, detailed {qp_detail}"
    );
    assert!(
        bytes_smooth * 4 < bytes_finest * 3,
        "{bytes_smooth} against {bytes_finest}"
    );
}
