use super::*;

/// The record layout written pixel by pixel, as the format describes it.
fn reference_record(mask: &Mask, raw: &RgbImage) -> Vec<u8> {
    let (x0, y0, x1, y1) = mask.bounding_box().unwrap_or((0, 0, 0, 0));
    let mut rec: Vec<u8> = [x0, y0, x1, y1]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let n = ((x1 - x0) * (y1 - y0)) as usize;
    let mut bits = vec![0u8; n.div_ceil(8)];
    let mut rgb = Vec::new();
    let mut i = 0;
    for y in y0..y1 {
        for x in x0..x1 {
            if mask.get(x, y) {
                bits[i / 8] |= 1 << (i % 8);
                rgb.extend_from_slice(&raw.get_pixel(x, y).0);
            }
            i += 1;
        }
    }
    rec.extend(bits);
    rec.extend(rgb);
    rec
}

#[test]
fn records_match_the_per_pixel_layout() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = vt_core::rng::Rng::new(17);
    for (w, h) in [(13u32, 9u32), (64, 3), (70, 9), (131, 5), (200, 2)] {
        let raw = RgbImage::from_fn(w, h, |x, y| image::Rgb([x as u8, y as u8, (x * y) as u8]));
        let path = dir.path().join(format!("o{w}x{h}.bin"));
        let mut writer = ObjectWriter::create(&path, w, h).unwrap();
        let mut want = Vec::new();
        // Sparse, dense, runs across words, a full box, an empty one.
        for density in [3u64, 50, 97, 100, 0] {
            let seed = rng.next_u64();
            let m = Mask::from_fn(w, h, |x, y| {
                vt_core::rng::mix(seed ^ ((x as u64) << 20) ^ y as u64) % 100 < density
            });
            writer.push(&m, &raw).unwrap();
            want.push(reference_record(&m, &raw));
        }
        writer.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let mut at = HEADER;
        for rec in &want {
            assert_eq!(&bytes[at..at + rec.len()], &rec[..], "{w}x{h}");
            at += rec.len();
        }
    }
}

/// A moving, textured scene: smooth shading, a sinusoidal texture drifting right and a
/// disc whose mask moves with it (frames of a real camera are smoother than noise).
fn moving_frames(w: u32, h: u32, n: usize) -> Vec<(Mask, RgbImage)> {
    (0..n)
        .map(|f| {
            let t = f as f32;
            let raw = RgbImage::from_fn(w, h, |x, y| {
                let (xf, yf) = (x as f32 - 1.5 * t, y as f32);
                let v = (xf * 0.21).sin() * (yf * 0.17).cos();
                image::Rgb([
                    (128.0 + 90.0 * v) as u8,
                    (64.0 + yf * 0.5 + 40.0 * v) as u8,
                    (200.0 - xf.abs() * 0.3).clamp(0.0, 255.0) as u8,
                ])
            });
            let (cx, cy) = (10.0 + 2.0 * t, h as f32 / 2.0);
            let mask = Mask::from_fn(w, h, |x, y| {
                let (dx, dy) = (x as f32 - cx, y as f32 - cy);
                dx * dx + dy * dy < 150.0 || (f % 5 == 0 && x < 3)
            });
            (mask, raw)
        })
        .collect()
}

fn write(path: &Path, frames: &[(Mask, RgbImage)], quality: StoreQuality) {
    let (w, h) = frames[0].1.dimensions();
    let mut writer = ObjectWriter::create_with(path, w, h, quality).unwrap();
    for (m, raw) in frames {
        writer.push(m, raw).unwrap();
    }
    writer.finish().unwrap();
}

/// The patch's pixels as (x, y, rgb), for comparing decodes.
fn patch_pixels(p: &vt_core::render::ObjectPatch) -> Vec<(u32, u32, [u8; 3])> {
    let mut v = Vec::new();
    for k in 0..(p.width * p.height) as usize {
        if p.mask[k] == 1 {
            let (x, y) = (p.x0 + k as u32 % p.width, p.y0 + k as u32 / p.width);
            v.push((x, y, [p.rgb[3 * k], p.rgb[3 * k + 1], p.rgb[3 * k + 2]]));
        }
    }
    v
}

#[test]
fn both_versions_keep_the_masks_lossless_keeps_the_pixels() {
    let dir = tempfile::tempdir().unwrap();
    // Odd sides: version 2 pads its pictures.
    let frames = moving_frames(67, 41, 21);
    for quality in [StoreQuality::Lossless, StoreQuality::default()] {
        let path = dir.path().join(format!("o_{quality}.bin"));
        write(&path, &frames, quality);
        let store = ObjectStore::load(&path).unwrap();
        match quality {
            // A quality target's store records the quantiser it chose.
            StoreQuality::Target { .. } => assert!(
                matches!(store.quality(), StoreQuality::H264 { qp } if (MIN_QP..=MAX_TARGET_QP).contains(&qp)),
                "{:?}",
                store.quality()
            ),
            q => assert_eq!(store.quality(), q),
        }
        assert_eq!((store.len(), store.size()), (21, (67, 41)));
        let mut patch = vt_core::render::ObjectPatch::default();
        let (mut se, mut count) = (0.0f64, 0usize);
        for (i, (m, raw)) in frames.iter().enumerate() {
            assert_eq!(&store.mask(i), m, "{quality}: frame {i}'s mask");
            store.decode_into(i, &mut patch).unwrap();
            let pixels = patch_pixels(&patch);
            assert_eq!(pixels.len() as u64, m.count_ones(), "{quality}: frame {i}");
            for (x, y, c) in pixels {
                assert!(m.get(x, y));
                let want = raw.get_pixel(x, y).0;
                if quality == StoreQuality::Lossless {
                    assert_eq!(c, want, "frame {i} at ({x}, {y})");
                }
                for k in 0..3 {
                    se += (c[k] as f64 - want[k] as f64).powi(2);
                }
                count += 3;
            }
        }
        // A floor only: this texture is harder than camera frames (saturated colour edges
        // that 4:2:0 blurs); tests/store_quality.rs holds real footage to 40 dB.
        let psnr = 10.0 * (255.0f64 * 255.0 / (se / count as f64).max(1e-12)).log10();
        assert!(
            psnr >= 37.0,
            "{quality}: {psnr:.2} dB against the raw frames"
        );
    }
}

#[test]
fn both_encoders_store_frames_smaller_than_a_macroblock() {
    // 9x5: padded to 16x16 for the encoder, cropped back when decoded.
    let frames = moving_frames(9, 5, 11);
    let dir = tempfile::tempdir().unwrap();
    for encoder in [H264Encoder::OpenH264, H264Encoder::X264] {
        if encoder == H264Encoder::X264 && !x264_available() {
            continue;
        }
        let path = dir.path().join(format!("o_{encoder:?}.bin"));
        let mut w =
            ObjectWriter::create_with_encoder(&path, 9, 5, StoreQuality::default(), encoder)
                .unwrap();
        for (m, raw) in &frames {
            w.push(m, raw).unwrap();
        }
        assert_eq!(w.len(), 11);
        w.finish().unwrap();
        let store = ObjectStore::load(&path).unwrap();
        let mut patch = vt_core::render::ObjectPatch::default();
        for (i, (m, raw)) in frames.iter().enumerate().rev() {
            store.decode_into(i, &mut patch).unwrap();
            let pixels = patch_pixels(&patch);
            assert_eq!(pixels.len() as u64, m.count_ones(), "{encoder:?} frame {i}");
            for (x, y, c) in pixels {
                let want = raw.get_pixel(x, y).0;
                for k in 0..3 {
                    assert!(c[k].abs_diff(want[k]) < 40, "{encoder:?} {i} ({x}, {y})");
                }
            }
        }
    }
}

#[test]
fn random_access_equals_sequential_decoding() {
    for encoder in [H264Encoder::OpenH264, H264Encoder::X264] {
        if encoder == H264Encoder::X264 && !x264_available() {
            println!("x264 skipped: ffmpeg with libx264 is not installed");
            continue;
        }
        random_access_with(encoder);
    }
}

fn random_access_with(encoder: H264Encoder) {
    let dir = tempfile::tempdir().unwrap();
    let frames = moving_frames(48, 32, 29);
    let path = dir.path().join("o.bin");
    let mut writer =
        ObjectWriter::create_with_encoder(&path, 48, 32, StoreQuality::default(), encoder).unwrap();
    for (m, raw) in &frames {
        writer.push(m, raw).unwrap();
    }
    writer.finish().unwrap();
    let store = ObjectStore::load(&path).unwrap();
    assert_eq!(store.len(), frames.len(), "{encoder:?}");
    // Every group starts with an IDR picture and its parameter sets (NAL types 7, 8, 5),
    // the other frames are P pictures (type 1): the groups decode on their own.
    for i in 0..frames.len() {
        let unit = store.bytes.with(
            store.index.parts_v2(i).1.start,
            store.index.parts_v2(i).1.len(),
            &mut Vec::new(),
            |u| {
                let mut types = Vec::new();
                for k in 0..u.len().saturating_sub(3) {
                    if u[k..k + 3] == [0, 0, 1] {
                        types.push(u[k + 3] & 0x1f);
                    }
                }
                types
            },
        );
        let types = unit.unwrap();
        let picture: Vec<u8> = types
            .iter()
            .copied()
            .filter(|&t| t == 1 || t == 5)
            .collect();
        if i % GOP as usize == 0 {
            assert!(
                types.contains(&7) && types.contains(&8),
                "{encoder:?} {i}: {types:?}"
            );
            assert_eq!(picture, [5], "{encoder:?} frame {i}: {types:?}");
        } else {
            assert_eq!(picture, [1], "{encoder:?} frame {i}: {types:?}");
        }
        assert!(
            !types.contains(&9),
            "{encoder:?} frame {i}: a delimiter left"
        );
    }
    drop(store);
    let decode = |store: &ObjectStore, i: usize| {
        let mut patch = vt_core::render::ObjectPatch::default();
        store.decode_into(i, &mut patch).unwrap();
        patch_pixels(&patch)
    };
    let sequential: Vec<_> = {
        let store = ObjectStore::load(&path).unwrap();
        (0..frames.len()).map(|i| decode(&store, i)).collect()
    };
    // Jumps both ways, within and across groups, repeats, loop wraps; each on a fresh store
    // and on one that has decoded other frames before.
    let order = [28, 3, 4, 17, 9, 9, 0, 27, 8, 7, 16, 15, 24, 1, 28, 5];
    let shared = ObjectStore::load(&path).unwrap();
    for &i in &order {
        assert_eq!(decode(&shared, i), sequential[i], "frame {i} after jumps");
        let fresh = ObjectStore::load(&path).unwrap();
        assert_eq!(decode(&fresh, i), sequential[i], "frame {i} alone");
    }
    // Near the frames themselves (the real-footage bound of 40 dB is in tests/store_quality;
    // this tiny pattern with saturated colours gets 39 dB from openh264).
    let (mut se, mut count) = (0f64, 0f64);
    for (i, (_, raw)) in frames.iter().enumerate() {
        for (x, y, c) in &sequential[i] {
            let want = raw.get_pixel(*x, *y).0;
            for k in 0..3 {
                se += (c[k] as f64 - want[k] as f64).powi(2);
                count += 1.0;
            }
        }
    }
    let psnr = 10.0 * (255.0f64.powi(2) / (se / count).max(1e-12)).log10();
    assert!(psnr > 35.0, "{encoder:?}: {psnr:.2} dB");
}

#[test]
fn a_second_decoder_starts_only_for_interleaved_runs() {
    let dir = tempfile::tempdir().unwrap();
    let frames = moving_frames(48, 32, 40);
    let path = dir.path().join("o.bin");
    let mut writer = ObjectWriter::create_with_encoder(
        &path,
        48,
        32,
        StoreQuality::default(),
        H264Encoder::OpenH264,
    )
    .unwrap();
    for (m, raw) in &frames {
        writer.push(m, raw).unwrap();
    }
    writer.finish().unwrap();
    let read = |order: &[usize]| {
        let store = ObjectStore::load(&path).unwrap();
        let mut patch = vt_core::render::ObjectPatch::default();
        for &i in order {
            store.decode_into(i, &mut patch).unwrap();
        }
        store.decoders_started()
    };
    // In order, and forward jumps across groups (seams sampled along a loop): one decoder.
    assert_eq!(read(&(0..40).collect::<Vec<_>>()), 1);
    assert_eq!(read(&[1, 2, 10, 11, 20, 21, 33, 34, 5, 6]), 1);
    // Two runs in two groups, read in turn (a switch fade's two runs of one view): the second
    // run gets its own decoder instead of restarting its group at every frame.
    let g = GOP as usize;
    let turns: Vec<usize> = (1..g).flat_map(|k| [k, g + k]).collect();
    assert_eq!(read(&turns), 2);
}

#[test]
fn access_units_split_at_their_delimiters() {
    // Two units behind delimiters (4- and 3-byte start codes), split across reads.
    let stream: Vec<u8> = [
        &[0, 0, 0, 1, 9, 0x10][..],
        &[0, 0, 0, 1, 0x67, 1, 2, 0, 0, 1, 0x65, 3, 4],
        &[0, 0, 1, 9, 0x30],
        &[0, 0, 1, 0x41, 5, 6, 0],
    ]
    .concat();
    let mut units = Vec::new();
    let mut buf = Vec::new();
    for (k, part) in stream.chunks(4).enumerate() {
        buf.extend_from_slice(part);
        let end = (k + 1) * 4 >= stream.len();
        assert!(split_units(&mut buf, end, |u| {
            units.push(u);
            true
        }));
    }
    assert_eq!(
        units,
        vec![
            vec![0, 0, 0, 1, 0x67, 1, 2, 0, 0, 1, 0x65, 3, 4],
            vec![0, 0, 1, 0x41, 5, 6, 0]
        ]
    );
    assert!(buf.is_empty());
}

#[test]
fn version_2_reads_records_on_demand_from_its_file() {
    let dir = tempfile::tempdir().unwrap();
    let frames = moving_frames(48, 32, 20);
    let path = dir.path().join("o.bin");
    write(&path, &frames, StoreQuality::default());
    let bytes = std::fs::read(&path).unwrap();
    let memory = ObjectStore::from_bytes(bytes.clone(), &path).unwrap();
    let file = ObjectStore::load(&path).unwrap();
    assert_eq!(file.byte_len(), bytes.len());
    let (mut a, mut b) = Default::default();
    // From the file: the same frames as from memory, from several threads at once.
    std::thread::scope(|s| {
        for t in 0..3 {
            let file = &file;
            s.spawn(move || {
                let mut patch = vt_core::render::ObjectPatch::default();
                for i in (t..20).chain((0..20).rev()) {
                    file.decode_into(i, &mut patch).unwrap();
                }
            });
        }
    });
    for i in [0, 1, 2, 13, 7, 19, 8] {
        memory.decode_into(i, &mut a).unwrap();
        file.decode_into(i, &mut b).unwrap();
        assert_eq!(patch_pixels(&a), patch_pixels(&b), "frame {i}");
        assert_eq!(memory.mask(i), file.mask(i), "frame {i}");
    }
    // A file cut short after loading: an error naming it, not a panic.
    std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    let fresh = ObjectStore::from_bytes(bytes, &path).unwrap();
    drop(fresh);
    let err = (0..20)
        .rev()
        .find_map(|i| file.decode_into(i, &mut b).err())
        .expect("the cut frames fail");
    assert!(err.to_string().contains("o.bin"), "{err}");
}

#[test]
fn other_versions_are_refused_with_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("o.bin");
    write(&path, &moving_frames(16, 16, 3), StoreQuality::default());
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[5] = b'9';
    let err = ObjectStore::from_bytes(bytes, &path)
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("version '9'") && err.contains("run vt analyze again"),
        "{err}"
    );
}

#[test]
fn round_trip_and_corruption() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("o.bin");
    let raw = RgbImage::from_fn(13, 9, |x, y| image::Rgb([x as u8, y as u8, 7]));
    let masks = [
        Mask::from_fn(13, 9, |x, y| (x + y) % 3 == 0 && x > 2),
        Mask::new(13, 9),
        Mask::from_fn(13, 9, |_, _| true),
    ];
    let mut w = ObjectWriter::create(&path, 13, 9).unwrap();
    for m in &masks {
        w.push(m, &raw).unwrap();
    }
    w.finish().unwrap();
    let s = ObjectStore::load(&path).unwrap();
    assert_eq!(s.len(), 3);
    for (i, m) in masks.iter().enumerate() {
        assert_eq!(&s.mask(i), m);
        s.frame(i)
            .unwrap()
            .for_each_pixel(|x, y, c| assert_eq!(c, raw.get_pixel(x, y).0));
    }
    let bytes = std::fs::read(&path).unwrap();
    for (cut, flip) in [(5, None), (0, Some(20)), (0, Some(bytes.len() - 20))] {
        let mut b = bytes[..bytes.len() - cut].to_vec();
        if let Some(i) = flip {
            b[i] ^= 0x5a;
        }
        std::fs::write(&path, &b).unwrap();
        let err = ObjectStore::load(&path)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            err.contains("corrupted"),
            "cut {cut} flip {flip:?}: {err:?}"
        );
    }
}

/// A view written again from its frame 0 (the analysis restarting it) replaces what was
/// written, not appends to it.
#[test]
fn a_view_started_again_is_written_anew() {
    use vt_core::analysis::Observer;
    let dir = tempfile::tempdir().unwrap();
    let mut stores = StoreWriter::with_quality(dir.path(), StoreQuality::Lossless);
    let frames = moving_frames(48, 32, 5);
    for (i, (m, raw)) in frames.iter().enumerate().take(3) {
        stores.object_frame(0, i, m, raw).unwrap();
    }
    for (i, (m, raw)) in frames.iter().enumerate() {
        stores.object_frame(0, i, m, raw).unwrap();
    }
    stores.finish().unwrap();
    let store = ObjectStore::load(&dir.path().join(crate::scene::objects_name(0))).unwrap();
    assert_eq!(store.len(), 5);
}

#[test]
fn a_quality_target_takes_the_largest_quantiser_predicted_to_keep_it() {
    use super::writer::qp_for;
    // Measured at the probe's quantiser: a step above loses 1 dB, a step below gains 0.45.
    assert_eq!(qp_for(42.9, 40.5), PROBE_QP + 2);
    assert_eq!(qp_for(40.5, 40.5), PROBE_QP);
    assert_eq!(qp_for(40.4, 40.5), PROBE_QP - 1);
    // Beyond either end: the finest quantiser, or the coarsest a target may take.
    assert_eq!(qp_for(20.0, 40.5), MIN_QP);
    assert_eq!(qp_for(99.0, 40.5), MAX_TARGET_QP);
}

#[test]
fn a_target_store_records_its_quantiser_and_reads_back_every_frame() {
    let dir = tempfile::tempdir().unwrap();
    // Fewer frames than a group (chosen at finish), exactly a group, and more.
    for n in [3, GOP as usize, 2 * GOP as usize + 3] {
        let frames = moving_frames(40, 24, n);
        let path = dir.path().join(format!("t{n}.bin"));
        write(&path, &frames, StoreQuality::default());
        let store = ObjectStore::load(&path).unwrap();
        assert_eq!(store.len(), n);
        assert!(matches!(store.quality(), StoreQuality::H264 { .. }));
        let mut patch = vt_core::render::ObjectPatch::default();
        for (i, (m, _)) in frames.iter().enumerate() {
            assert_eq!(&store.mask(i), m, "frame {i} of {n}");
            store.decode_into(i, &mut patch).unwrap();
        }
    }
}
