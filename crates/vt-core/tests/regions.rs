//! Per-region loops against independent truth: a scene whose left half repeats every 5 frames
//! and right half every 7 (no single loop shorter than 35 exists), and brute force over every
//! labelling of a tiny problem.

use image::{Rgb, RgbImage};
use vt_core::regions::{compose, quality, reduce, solve, Label, Problem, RegionParams, Strips};
use vt_core::rng::mix_at;
use vt_core::Mask;

/// Two tiles' indices and the pixels either side of the edge they share.
type Edge = (usize, usize, Vec<(u32, u32)>);

/// Random texture per phase: pixel (x, y) at phase `k` of a region with `seed`.
fn texel(seed: u64, k: usize, x: u32, y: u32) -> u8 {
    (mix_at(seed, (k as u64) << 32 | (y as u64) << 16 | x as u64) >> 56) as u8
}

/// `n` frames of `w x h`: columns left of `split` repeat every `p_left`, the rest every
/// `p_right`.
fn two_periods(
    n: usize,
    w: u32,
    h: u32,
    split: u32,
    p_left: usize,
    p_right: usize,
) -> Vec<RgbImage> {
    (0..n)
        .map(|i| {
            RgbImage::from_fn(w, h, |x, y| {
                let v = if x < split {
                    texel(1, i % p_left, x, y)
                } else {
                    texel(2, i % p_right, x, y)
                };
                Rgb([v, v / 2, 255 - v])
            })
        })
        .collect()
}

#[test]
fn each_half_gets_its_own_true_period_and_loops_exactly() {
    let (w, h, n) = (64u32, 32u32, 30usize);
    let frames = two_periods(n, w, h, 32, 5, 7);
    let masks: Vec<Mask> = (0..n).map(|_| Mask::new(w, h)).collect();
    let params = RegionParams {
        tile: 16,
        scale: 2,
        max_length: 35,
        feather: 4,
        ..Default::default()
    };
    let rl = solve(&frames, None, None, 5, &params).unwrap();
    // Periods dividing a length up to 35 with room in 30 frames: the only length both halves
    // can loop exactly in is 35 (periods 5 and 7).
    assert_eq!(rl.length, 35);
    let (cols, rows) = rl.grid;
    assert_eq!((cols, rows), (4, 2));
    for r in 0..rows {
        for c in 0..cols {
            let want = if c < 2 { 5 } else { 7 };
            assert_eq!(rl.labels[r * cols + c].period, want, "tile ({c}, {r})");
        }
    }
    let (baked, _) = compose(&frames, &masks, &rl, params.feather);
    assert_eq!(baked.len(), 36);
    assert_eq!(baked[35], baked[0]);
    // Away from the feather band at x = 32, every baked pixel is the true periodic signal at
    // output time t plus a constant shift per half: the loop has no seam at all.
    for (x, seed, p) in [(5u32, 1u64, 5usize), (28, 1, 5), (36, 2, 7), (60, 2, 7)] {
        let y = 9;
        let shift = (0..p)
            .find(|&c| texel(seed, c % p, x, y) == baked[0].get_pixel(x, y)[0])
            .unwrap();
        for (t, f) in baked.iter().enumerate() {
            assert_eq!(
                f.get_pixel(x, y)[0],
                texel(seed, (t + shift) % p, x, y),
                "x {x} t {t}"
            );
        }
    }
    let q = quality(&baked, &frames, &rl, None);
    // Only the feather band blends frames: the rest is source content exactly.
    assert!(q.source_error < 4.0, "{q:?}");
    assert!(q.tile_wrap <= 1.0 + 1e-9, "{q:?}");
}

#[test]
fn a_single_periodic_scene_keeps_its_exact_period() {
    let (w, h, n) = (48u32, 32u32, 40usize);
    let frames = two_periods(n, w, h, w, 6, 6);
    let params = RegionParams {
        tile: 16,
        scale: 2,
        max_length: 36,
        ..Default::default()
    };
    let rl = solve(&frames, None, Some(6), 6, &params).unwrap();
    // Every tile loops on a multiple of the true period, with no temporal cost.
    for l in &rl.labels {
        assert_eq!(l.period % 6, 0, "{l:?}");
    }
    assert_eq!(rl.energy, 0.0);
}

#[test]
fn icm_reaches_the_brute_force_optimum_on_a_tiny_case() {
    // 2 x 2 tiles of 4 px, 9 frames of noise with a weak period-3 component: a few labels.
    let (w, h, n) = (8u32, 8u32, 9usize);
    let frames: Vec<RgbImage> = (0..n)
        .map(|i| {
            RgbImage::from_fn(w, h, |x, y| {
                let base = texel(3, i % 3, x, y) / 2;
                let noise = texel(4, i, x, y) / 4;
                let v = base + noise;
                Rgb([v, v, v])
            })
        })
        .collect();
    let r = reduce(&frames, None, 1);
    let strips = Strips::new(&r, 4);
    for lambda in [0.0, 1.0, 10.0] {
        let pb = Problem::new(&r, 4, 6, 2, lambda, &strips).unwrap();
        let nl = pb.labels.len();
        // Labels: periods 2, 3 and 6 (divisors of 6 with room in 9 frames), every start.
        let want: usize = [2usize, 3, 6].iter().map(|p| n - 1 - p).sum();
        assert_eq!(nl, want);
        // The energy against one computed here from the frames.
        let energy_here = |lab: &[usize]| -> f64 {
            let d = |i: usize, j: usize, px: &[(u32, u32)]| -> f64 {
                px.iter()
                    .map(|&(x, y)| {
                        let (a, b) = (frames[i].get_pixel(x, y), frames[j].get_pixel(x, y));
                        (0..3)
                            .map(|c| (a[c] as f64 - b[c] as f64).powi(2))
                            .sum::<f64>()
                    })
                    .sum()
            };
            let tile_px = |t: usize| -> Vec<(u32, u32)> {
                let (c, r) = ((t % 2) as u32, (t / 2) as u32);
                (0..16).map(|k| (c * 4 + k % 4, r * 4 + k / 4)).collect()
            };
            let mut e = 0.0;
            for t in 0..4 {
                let l: Label = pb.labels[lab[t]];
                let px = tile_px(t);
                e += d(l.start, l.start + l.period, &px)
                    + d(l.start - 1, l.start + l.period - 1, &px);
            }
            // Edges: the pixel columns/rows either side of each shared edge.
            let edges: [Edge; 4] = [
                (0, 1, (0..4).flat_map(|y| [(3, y), (4, y)]).collect()),
                (2, 3, (4..8).flat_map(|y| [(3, y), (4, y)]).collect()),
                (0, 2, (0..4).flat_map(|x| [(x, 3), (x, 4)]).collect()),
                (1, 3, (4..8).flat_map(|x| [(x, 3), (x, 4)]).collect()),
            ];
            for (a, b, px) in edges {
                if lab[a] == lab[b] {
                    continue;
                }
                let (la, lb) = (pb.labels[lab[a]], pb.labels[lab[b]]);
                let s: f64 = (0..6).map(|t| d(la.frame(t), lb.frame(t), &px)).sum();
                e += lambda * s / 6.0;
            }
            e
        };
        let mut best = (f64::INFINITY, vec![0; 4]);
        for code in 0..nl.pow(4) {
            let lab: Vec<usize> = (0..4).map(|k| code / nl.pow(k) % nl).collect();
            let e = pb.energy(&lab);
            if e < best.0 {
                best = (e, lab);
            }
        }
        let got = pb.icm(pb.single(), 50);
        let e_icm = pb.energy(&got);
        let rel = |a: f64, b: f64| (a - b).abs() <= 1e-3 * b.abs().max(1.0);
        assert!(rel(energy_here(&got), e_icm), "lambda {lambda}");
        assert!(rel(energy_here(&best.1), best.0), "lambda {lambda}");
        assert!(e_icm >= best.0 - 1e-6);
        // ICM's result is a local minimum: no single tile's change lowers the energy.
        for t in 0..4 {
            for l in 0..nl {
                let mut other = got.clone();
                other[t] = l;
                assert!(pb.energy(&other) >= e_icm - 1e-6);
            }
        }
        assert!(
            rel(e_icm, best.0),
            "lambda {lambda}: icm {e_icm} brute {}",
            best.0
        );
    }
}

#[test]
fn the_wrap_correction_removes_a_drift_that_never_repeats() {
    // A faint texture (0 or 1 grey level) repeating every 6 frames under a brightness drift of
    // 1 grey level per frame: no frame repeats, and a 6-frame loop's wrap steps back 6 levels
    // at once, 6 ordinary steps. The temporal Poisson correction spreads that step over the
    // whole cycle (c_k = D ((p - 1) / 2 - k) / p with D = 6 everywhere; spread over fewer
    // frames, each would carry more than the default spread of an ordinary step), which cancels the
    // drift exactly: the baked loop is the texture alone plus one constant, at every pixel,
    // frame and low-pass sigma.
    let (w, h, n, p) = (32u32, 32u32, 30usize, 6usize);
    let tex = |k: usize, x: u32, y: u32| 60 + texel(5, k % p, x, y) / 128;
    let frames: Vec<RgbImage> = (0..n)
        .map(|i| {
            RgbImage::from_fn(w, h, |x, y| {
                let v = tex(i, x, y) + i as u8;
                Rgb([v, v, v])
            })
        })
        .collect();
    let masks: Vec<Mask> = (0..n).map(|_| Mask::new(w, h)).collect();
    let start = 7;
    for blend in [None, Some(0.0), Some(3.0)] {
        let mut rl = vt_core::regions::single_loop(Label { start, period: p }, (w, h), 16);
        rl.blend = blend;
        let (baked, _) = compose(&frames, &masks, &rl, 4);
        assert_eq!(baked.len(), p + 1);
        // Output frame t shows source frame start + t (the loop starts at its start).
        let offsets: Vec<i32> = (0..p)
            .flat_map(|t| {
                let b = &baked[t];
                (0..h).flat_map(move |y| {
                    (0..w).map(move |x| b.get_pixel(x, y)[0] as i32 - tex(start + t, x, y) as i32)
                })
            })
            .collect();
        let (lo, hi) = (offsets.iter().min().unwrap(), offsets.iter().max().unwrap());
        match blend {
            // Without the correction the drift stays: offsets start..start + p - 1.
            None => assert_eq!((*lo, *hi), (start as i32, (start + p - 1) as i32)),
            // With it, one constant (start + 2.5 rounded up).
            Some(_) => assert_eq!(
                (*lo, *hi),
                (start as i32 + 3, start as i32 + 3),
                "{blend:?}"
            ),
        }
    }
}

/// A wrap mismatch smaller than the tile's ordinary step is left alone (the correction is not
/// spread at all): the baked frames are the source's.
#[test]
fn a_wrap_within_an_ordinary_step_is_not_corrected() {
    let (w, h, n, p, start) = (32u32, 32u32, 30usize, 6usize, 7usize);
    // A strong texture (steps of tens of grey levels) under a drift of 1 level per frame.
    let frames: Vec<RgbImage> = (0..n)
        .map(|i| {
            RgbImage::from_fn(w, h, |x, y| {
                let v = 60 + texel(5, i % p, x, y) / 4 + i as u8;
                Rgb([v, v, v])
            })
        })
        .collect();
    let masks: Vec<Mask> = (0..n).map(|_| Mask::new(w, h)).collect();
    let mut rl = vt_core::regions::single_loop(Label { start, period: p }, (w, h), 16);
    rl.blend = Some(0.0);
    assert!(vt_core::regions::spreads(&frames, &rl)
        .iter()
        .all(|&k| k == 1));
    let (baked, _) = compose(&frames, &masks, &rl, 4);
    for t in 0..p {
        assert_eq!(baked[t], frames[start + t], "frame {t}");
    }
}

/// The analysis makes per-region loops from the frame cache when the view's frames fit it; when
/// they do not, from its source window decoded again and packed losslessly within the cache's
/// budget (the same loop, the same baked frames); when even that does not fit, the view keeps
/// the thesis's loop and says how many bytes it would need (printed by `vt analyze`), rather
/// than dropping the request silently.
#[test]
fn the_analysis_says_when_per_region_loops_do_not_fit_the_cache() {
    use vt_core::analysis::{analyze, AnalyzeParams, FrameSource, MemorySource, Observer};
    // The two-period scene at twice its size (each texel 2x2 pixels: smooth enough to pack).
    let (w, h, n) = (128u32, 64u32, 40usize);
    let scene: Vec<RgbImage> = two_periods(n, w / 2, h / 2, 32, 5, 7)
        .iter()
        .map(|f| image::imageops::resize(f, w, h, image::imageops::FilterType::Nearest))
        .collect();
    /// The frames the analysis hands the object store, the last time it wrote each index.
    #[derive(Default)]
    struct Store(Vec<RgbImage>);
    impl Observer for Store {
        fn object_frame(
            &mut self,
            _view: usize,
            frame: usize,
            _mask: &vt_core::Mask,
            raw: &RgbImage,
        ) -> vt_core::Result<()> {
            self.0.truncate(frame);
            self.0.push(raw.clone());
            Ok(())
        }
    }
    let run = |cache_bytes: usize| {
        let mut src = MemorySource {
            name: "two periods".into(),
            frames: scene.clone(),
        };
        let params = AnalyzeParams {
            regions: Some(RegionParams {
                tile: 16,
                scale: 2,
                max_length: 35,
                feather: 4,
                ..Default::default()
            }),
            cache_bytes,
            // Every frame in the median whether they are cached or stream.
            median_frames: 0,
            loops: vt_core::loops::LoopParams {
                window: 3,
                min_length: 10,
            },
            ..Default::default()
        };
        let mut sources: Vec<&mut dyn FrameSource> = vec![&mut src];
        let mut store = Store::default();
        let a = analyze(&mut sources, &[], &params, &mut store).unwrap();
        (a, store.0)
    };
    let (fits, cached_frames) = run(AnalyzeParams::default().cache_bytes);
    let v = &fits.views[0];
    let cached = v.region_loop.as_ref().expect("made from the cache");
    assert_eq!(v.regions_over_cache, None);
    assert_eq!(cached_frames.len(), v.n_frames);
    assert_eq!(v.n_frames, cached.chosen.length + 1);
    // Four fifths of the frames fit the cache: they stream, and the loop's window (all 40 frames
    // here) is decoded again and packed within the budget. Packing is lossless: the same loop,
    // the same baked frames.
    let frame = 3 * (w * h) as usize;
    // The label search over the 40 frames is counted in the budget beside them.
    let search = vt_core::regions::search_bytes(
        (w, h),
        n,
        &RegionParams {
            tile: 16,
            scale: 2,
            ..Default::default()
        },
    );
    let (streamed, streamed_frames) = run(n * frame * 4 / 5 + search);
    let v = &streamed.views[0];
    let packed = v.region_loop.as_ref().unwrap_or_else(|| {
        panic!(
            "made from the packed window, not {:?} bytes",
            v.regions_over_cache
        )
    });
    let timeless = |r: &vt_core::regions::RegionLoop| vt_core::regions::RegionLoop {
        solve_secs: 0.0,
        ..r.clone()
    };
    assert_eq!(timeless(&packed.chosen), timeless(&cached.chosen));
    assert_eq!(v.n_frames, cached.chosen.length + 1);
    assert_eq!(
        streamed_frames, cached_frames,
        "the baked frames, byte for byte"
    );
    // Room for the packed window but not for the label search beside it: the thesis's loop,
    // and a budget above the one given.
    let tight = n * frame * 4 / 5;
    let (no_room, _) = run(tight);
    let v = &no_room.views[0];
    assert!(v.region_loop.is_none());
    let need = v.regions_over_cache.expect("says what it would need");
    assert!(
        need > tight as u64 && need <= (tight + search) as u64 + 1,
        "{need}"
    );
    // Two frames' room: no window fits; the thesis's loop, and the budget that would have done.
    let (over, over_frames) = run(2 * frame);
    let v = &over.views[0];
    assert!(v.region_loop.is_none());
    let need = v.regions_over_cache.expect("says what it would need");
    // The loop's frames packed (at most the window's 40, each at most a raw frame and a bit)
    // and the masks beside them: more than the cache, less than everything raw.
    assert!(
        need > 2 * frame as u64 && need < 2 * (n * frame) as u64,
        "{need}"
    );
    assert_eq!(over_frames.len(), n, "the source frames stay in the store");
}

/// `n` frames of `w x h` in which a sinusoid moves smoothly, each of the vertical bands
/// `x < splits[k]` repeating every `periods[k]` frames (a wrong wrap jumps, an ordinary step is
/// small); plus sensor noise of `0..noise` grey levels and a brightening of `drift` grey levels
/// per frame, neither of which repeats.
fn waves(
    n: usize,
    (w, h): (u32, u32),
    splits: &[u32],
    periods: &[usize],
    (noise, drift): (u8, f64),
) -> Vec<RgbImage> {
    (0..n)
        .map(|i| {
            RgbImage::from_fn(w, h, |x, y| {
                let band = splits.iter().position(|&s| x < s).unwrap_or(splits.len());
                let p = periods[band];
                let phase = (x + 2 * y) as f64 / 12.0 + (i % p) as f64 / p as f64;
                let e = texel(9, i, x, y) % noise.max(1);
                let v = (100.0 + 20.0 * (std::f64::consts::TAU * phase).sin() + drift * i as f64)
                    as u8
                    + e;
                Rgb([v, v / 2, 255 - v])
            })
        })
        .collect()
}

/// The default (`--loops auto`): per-region loops only where they measure better than the
/// thesis's loop. An exact repeat keeps its exact loop (measured, nothing else tried); a wave
/// brightening
/// as it moves (light changing during the shot: no frame repeats, and every loop wraps back
/// to a darker frame) gets the per-region loop, whose wrap correction spreads that step over
/// the cycle; one wave under sensor noise (no exact repeat, but the
/// thesis's loop wraps as it steps) keeps the thesis's loop without trying.
#[test]
fn by_default_per_region_loops_are_kept_only_where_they_are_better() {
    use vt_core::analysis::{analyze, AnalyzeParams, FrameSource, MemorySource, Quiet};
    let (w, h) = (96u32, 32u32);
    let run_with = |frames: Vec<RgbImage>, max_length: usize, cache_bytes: usize| {
        let mut src = MemorySource {
            name: "two periods".into(),
            frames,
        };
        let mut params = AnalyzeParams {
            loops: vt_core::loops::LoopParams {
                window: 3,
                min_length: 5,
            },
            cache_bytes,
            ..Default::default()
        };
        let rp = params
            .regions
            .as_mut()
            .expect("per-region loops are on by default");
        assert!(rp.only_if_better);
        (rp.tile, rp.feather, rp.max_length) = (16, 4, max_length);
        let mut sources: Vec<&mut dyn FrameSource> = vec![&mut src];
        analyze(&mut sources, &[], &params, &mut Quiet).unwrap()
    };
    let run =
        |frames, max_length| run_with(frames, max_length, AnalyzeParams::default().cache_bytes);
    // 45 frames hold the common period: the thesis's loop is exact and stays.
    let exact = run(waves(45, (w, h), &[48], &[5, 7], (0, 0.0)), 35);
    let v = &exact.views[0];
    assert_eq!(v.best_loop.cost, 0);
    assert_eq!(v.best_loop.len() % 35, 0);
    assert!(v.region_loop.is_none() && v.region_rejected.is_none());
    let q = v.region_not_needed.expect("the thesis's loop is measured");
    assert!(!q.shows(), "{q:?}");
    assert_eq!(v.n_frames, 45);
    // A wave brightening by 3 grey levels a frame: the per-region loop.
    let split = run(waves(30, (w, h), &[], &[6], (0, 3.0)), 35);
    let v = &split.views[0];
    let res = v
        .region_loop
        .as_ref()
        .expect("the per-region loop is better");
    assert!(res.quality.better_than(&res.single));
    // The thesis's loop jumps back to darker frames; the per-region loop does not.
    assert!(res.single.tile_wrap > 1.5, "{:?}", res.single);
    assert!(res.quality.tile_wrap < 1.2, "{:?}", res.quality);
    let l = res.chosen.length;
    assert_eq!(
        (v.best_loop.start, v.best_loop.end, v.n_frames),
        (0, l, l + 1)
    );
    // One wave under noise: the thesis's loop wraps as it steps and stays.
    let kept = run(waves(30, (w, h), &[], &[6], (6, 0.0)), 35);
    let v = &kept.views[0];
    let q = v.region_not_needed.expect("the thesis's loop is measured");
    assert!(!q.shows(), "{q:?}");
    assert!(v.region_loop.is_none() && v.region_rejected.is_none());
    assert_eq!(v.n_frames, 30);
    // Without a frame cache the thesis's loop is measured on its frames decoded once more, as
    // they come: the same figures, and nothing packed for a loop that needs nothing.
    for (frames, cached) in [
        (waves(45, (w, h), &[48], &[5, 7], (0, 0.0)), &exact),
        (waves(30, (w, h), &[], &[6], (6, 0.0)), &kept),
    ] {
        let streamed = run_with(frames, 35, 0);
        let (a, b) = (&streamed.views[0], &cached.views[0]);
        assert_eq!(a.region_not_needed, b.region_not_needed);
        assert_eq!(a.regions_over_cache, None, "nothing was packed");
        assert_eq!((a.best_loop, a.n_frames), (b.best_loop, b.n_frames));
    }
}
