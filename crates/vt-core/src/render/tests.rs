use super::*;
use crate::model::MotionModel;

#[test]
fn absurd_crossfade_is_an_error_not_an_overflow() {
    for crossfade in [MAX_CROSSFADE + 1, usize::MAX] {
        let params = RenderParams {
            crossfade,
            ..RenderParams::default()
        };
        let e = Renderer::new(tiny(), params).err().expect("refused");
        assert!(e.to_string().contains("crossfade"), "{e}");
    }
    let params = RenderParams {
        crossfade: MAX_CROSSFADE,
        gain_compensation: false,
        ..RenderParams::default()
    };
    assert!(Renderer::new(tiny(), params).is_ok());
}

#[test]
fn dissolve_spreads_the_wrap_over_in_between_frames() {
    // View 0 loops 1..=5: frames 2, 3, 4, 5, then the wrap to 2. With dissolve 2 the wrap
    // and the frame after show the last frame (5) dissolving into frame 2 + 2 = 4, weights
    // 1/3 and 2/3; then play goes on from 4 unblended.
    let grey = |params: RenderParams| {
        played(params, &[0.0; 7])
            .into_iter()
            .map(|(_, frame, grey)| (frame, grey))
            .collect::<Vec<_>>()
    };
    let plain = RenderParams {
        gain_compensation: false,
        ..RenderParams::default()
    };
    assert_eq!(
        grey(plain),
        [
            (2, 30),
            (3, 40),
            (4, 50),
            (5, 60),
            (2, 30),
            (3, 40),
            (4, 50)
        ]
    );
    let dissolved = RenderParams {
        dissolve: 2,
        ..plain
    };
    // 60 + (50 - 60) / 3 = 56.67 -> 57; 60 + 2 (50 - 60) / 3 = 53.33 -> 53.
    assert_eq!(
        grey(dissolved),
        [
            (2, 30),
            (3, 40),
            (4, 50),
            (5, 60),
            (2, 57),
            (3, 53),
            (4, 50)
        ]
    );
    let both = RenderParams {
        crossfade: 1,
        ..dissolved
    };
    let e = Renderer::new(tiny(), both).err().expect("refused");
    assert!(e.to_string().contains("dissolve"), "{e}");
}

/// Solid 4x4 objects whose grey level is 10 x (frame + 1) + 100 x view, so a blend's weights
/// show.
struct SolidByView;
impl ObjectFrames for SolidByView {
    fn decode_into(&self, view: usize, frame: usize, patch: &mut ObjectPatch) -> Result<()> {
        patch.reset(0, 0, 4, 4);
        patch.rgb.fill(10 * (frame as u8 + 1) + 100 * view as u8);
        patch.mask.fill(1);
        Ok(())
    }
}

/// (view, frame, grey at the object) of each output frame along `qs`.
fn played(params: RenderParams, qs: &[f64]) -> Vec<(usize, usize, u8)> {
    let s = std::sync::Arc::new(tiny());
    let mut r = Renderer::new(s.clone(), params).unwrap();
    let mut p = Player::new();
    let mut out = RgbImage::new(4, 4);
    qs.iter()
        .map(|&q| {
            let c = p.advance(&s, q).unwrap();
            r.render_into(&SolidByView, q, &c, &mut out).unwrap();
            (c.view, c.frame, out.get_pixel(1, 1).0[0])
        })
        .collect()
}

#[test]
fn switch_fade_blends_the_old_views_own_loop_into_the_new_view() {
    let plain = RenderParams {
        gain_compensation: false,
        switch_fade: 0,
        ..RenderParams::default()
    };
    let faded = RenderParams {
        switch_fade: 2,
        ..plain
    };
    // View 0 plays 2, 3; the switch at the tie goes to view 1's t_1(3, 0) + 1 = 4 (150), then
    // 5 (160), 6 (170). Hard: straight to 150. Faded over 2 frames: view 0's continuation 4
    // (50) and 5 (60) fade out with weights 2/3 and 1/3: 50 + 100 / 3 = 83.3, 60 + 2 x 100 / 3
    // = 126.7; the third frame is view 1's alone.
    let qs = [0.0, 0.0, 0.5, 0.5, 0.5];
    assert_eq!(
        played(plain, &qs),
        [
            (0, 2, 30),
            (0, 3, 40),
            (1, 4, 150),
            (1, 5, 160),
            (1, 6, 170)
        ]
    );
    assert_eq!(
        played(faded, &qs),
        [(0, 2, 30), (0, 3, 40), (1, 4, 83), (1, 5, 127), (1, 6, 170)]
    );
    // Leaving view 0 from its loop's end n = 5: what it would have shown next is m + 1 = 2
    // (30), not frame 6. View 1 shows t_1(5, 0) + 1 = 6 (170): 30 + 140 / 3 = 76.7. Then view 1
    // wraps (6 is its n) and the wrap ends the fade: 3 (140) alone.
    let qs = [0.0, 0.0, 0.0, 0.0, 0.5, 0.5];
    assert_eq!(
        played(faded, &qs),
        [
            (0, 2, 30),
            (0, 3, 40),
            (0, 4, 50),
            (0, 5, 60),
            (1, 6, 77),
            (1, 3, 140)
        ]
    );
    // A crossfade takes switches too, from the frame after the last one shown (6: 70), frame
    // by frame: one frame, weight 1/2: (70 + 170) / 2.
    let crossfaded = RenderParams {
        crossfade: 1,
        ..faded
    };
    assert_eq!(played(crossfaded, &qs)[4], (1, 6, 120));
    // The default fades switches, over DEFAULT_SWITCH_FADE frames.
    assert!(RenderParams::default().switch_fade > 0);
    let e = Renderer::new(
        tiny(),
        RenderParams {
            switch_fade: MAX_CROSSFADE + 1,
            ..plain
        },
    )
    .err()
    .expect("refused");
    assert!(e.to_string().contains("switch_fade"), "{e}");
}

#[test]
fn a_plain_render_leaves_the_fade_in_progress_as_it_was() {
    // What the seam meter does at every fade frame: render what the old view would have shown,
    // between the faded frames. The faded frames must not change.
    let params = RenderParams {
        gain_compensation: false,
        switch_fade: 2,
        ..RenderParams::default()
    };
    let s = std::sync::Arc::new(tiny());
    let mut r = Renderer::new(s.clone(), params).unwrap();
    let mut p = Player::new();
    let (mut out, mut other) = (RgbImage::new(4, 4), RgbImage::new(4, 4));
    let mut got = Vec::new();
    for q in [0.0, 0.0, 0.5, 0.5, 0.5] {
        let c = p.advance(&s, q).unwrap();
        r.render_into(&SolidByView, q, &c, &mut out).unwrap();
        got.push(out.get_pixel(1, 1).0[0]);
        if let Some((v, j)) = r.switch_fade_from() {
            r.render_plain_into(&SolidByView, q, v, j, &mut other)
                .unwrap();
            assert_eq!(
                other.get_pixel(1, 1).0[0],
                10 * (j as u8 + 1),
                "view 0 frame {j}"
            );
        }
    }
    assert_eq!(got, [30, 40, 83, 127, 170]);
    // The old view may lie beyond q's pair once q moves on (view 2 at q = 0.2): it is placed by
    // its own homography to q, not refused.
    r.render_plain_into(&SolidByView, 0.2, 2, 3, &mut other)
        .unwrap();
}

/// No moving objects: the frame is the blended background alone.
struct NoObjects;
impl ObjectFrames for NoObjects {
    fn decode_into(&self, _view: usize, _frame: usize, patch: &mut ObjectPatch) -> Result<()> {
        patch.reset(0, 0, 0, 0);
        Ok(())
    }
}

#[test]
fn kept_background_equals_a_fresh_render() {
    // The background is blended into the frame, kept only once q stays, then copied: every
    // frame of a path that moves, stays, jumps back and stays must equal the first frame of
    // a new renderer at that q (which blends it afresh).
    let mut scene = tiny();
    for (p, v) in scene.views.iter_mut().enumerate() {
        v.background = RgbImage::from_fn(23, 17, |x, y| {
            image::Rgb([(x * 11 + y * 3) as u8, (y * 13 + p as u32 * 40) as u8, 90])
        });
    }
    let scene = std::sync::Arc::new(scene);
    let params = RenderParams::default();
    let mut r = Renderer::new(scene.clone(), params).unwrap();
    let mut p = Player::new();
    let mut out = RgbImage::new(23, 17);
    for q in [0.3, 0.3, 0.3, 0.55, 0.55, 1.2, 0.3, 0.3, 2.0, 2.0, 2.0] {
        let c = p.advance(&scene, q).unwrap();
        r.render_into(&NoObjects, q, &c, &mut out).unwrap();
        let mut fresh = Renderer::new(scene.clone(), params).unwrap();
        let mut want = RgbImage::new(23, 17);
        fresh.render_into(&NoObjects, q, &c, &mut want).unwrap();
        assert!(out == want, "q {q}");
        assert!(
            out.as_raw().iter().any(|&v| v != 0),
            "q {q}: a textured frame"
        );
    }
}

#[test]
fn background_reuse_shows_the_kept_background_only_within_its_threshold() {
    let mut scene = tiny();
    for (p, v) in scene.views.iter_mut().enumerate() {
        v.background = RgbImage::from_fn(23, 17, |x, y| {
            image::Rgb([(x * 11 + y * 3) as u8, (y * 13 + p as u32 * 40) as u8, 90])
        });
    }
    let scene = std::sync::Arc::new(scene);
    let params = RenderParams {
        background_reuse_px: 0.05,
        ..RenderParams::default()
    };
    let fresh = |q: f64| {
        let mut r = Renderer::new(scene.clone(), RenderParams::default()).unwrap();
        let c = Player::new().advance(&scene, q).unwrap();
        let mut out = RgbImage::new(23, 17);
        r.render_into(&NoObjects, q, &c, &mut out).unwrap();
        out
    };
    let mut r = Renderer::new(scene.clone(), params).unwrap();
    let mut p = Player::new();
    let mut out = RgbImage::new(23, 17);
    let mut show = |q: f64| {
        let c = p.advance(&scene, q).unwrap();
        r.render_into(&NoObjects, q, &c, &mut out).unwrap();
        (out.clone(), r.background_blends())
    };
    // The views' points are 1 px apart, so q moves the background 1 px per view.
    assert_eq!(show(0.3), (fresh(0.3), 1));
    // 0.0001 px: the kept background, not the exact one.
    let (frame, blends) = show(0.3001);
    assert_eq!((frame == fresh(0.3), blends), (true, 1));
    assert!(fresh(0.3001) != fresh(0.3), "the exact frames differ");
    // 0.1 px, over the threshold: blended again, exactly.
    assert_eq!(show(0.4), (fresh(0.4), 2));
    // Another pair of views: blended whatever the distance.
    assert_eq!(show(1.0), (fresh(1.0), 3));
    for bad in [-0.1, f64::NAN, MAX_BACKGROUND_REUSE_PX + 0.1] {
        let params = RenderParams {
            background_reuse_px: bad,
            ..RenderParams::default()
        };
        let e = Renderer::new(scene.clone(), params).err().expect("refused");
        assert!(e.to_string().contains("background_reuse_px"), "{e}");
    }
}

/// A 3-view scene with tiny hand-made tables, for eq. (6) step by step.
fn tiny() -> RenderScene {
    let pts = |dx: f64| {
        vec![
            Point::new(dx, 0.0),
            Point::new(10.0 + dx, 0.0),
            Point::new(10.0 + dx, 10.0),
            Point::new(dx, 10.0),
        ]
    };
    let view = |m, n, next: Vec<Option<usize>>, prev: Vec<Option<usize>>, dx| RenderView {
        background: RgbImage::new(4, 4),
        loop_start: m,
        loop_end: n,
        to_next: next,
        to_prev: prev,
        points: pts(dx),
        dynamic: None,
        to_next_seam: Vec::new(),
        to_prev_seam: Vec::new(),
    };
    let none = vec![None; 8];
    RenderScene {
        parallax: Vec::new(),
        views: vec![
            view(
                1,
                5,
                vec![
                    Some(0),
                    Some(1),
                    Some(2),
                    Some(3),
                    Some(4),
                    Some(5),
                    Some(5),
                    Some(5),
                ],
                none.clone(),
                0.0,
            ),
            view(
                2,
                6,
                vec![
                    Some(6),
                    Some(5),
                    Some(4),
                    Some(3),
                    Some(2),
                    Some(1),
                    Some(0),
                    Some(0),
                ],
                vec![Some(3); 8],
                1.0,
            ),
            view(
                0,
                4,
                none.clone(),
                vec![
                    Some(2),
                    Some(2),
                    Some(2),
                    Some(2),
                    Some(2),
                    Some(2),
                    Some(2),
                    Some(2),
                ],
                2.0,
            ),
        ],
        model: MotionModel::Translation,
    }
}

#[test]
fn eq6_step_by_step() {
    let s = tiny();
    let mut p = Player::new();
    let mut run = |q: f64| {
        let c = p.advance(&s, q).unwrap();
        (c.view, c.frame, c.step)
    };
    // Start in view 0 at m + 1 = 2, play to n = 5, wrap to 2.
    assert_eq!(run(0.0), (0, 2, Step::Start));
    assert_eq!(run(0.2), (0, 3, Step::Play));
    assert_eq!(run(0.49), (0, 4, Step::Play));
    assert_eq!(run(0.1), (0, 5, Step::Play));
    assert_eq!(run(0.0), (0, 2, Step::Wrap));
    // q - f = 0.5 exactly: qbar = c = 1. Switch: t_1(2, 0) = next[2] = 2, show 3.
    assert_eq!(run(0.5), (1, 3, Step::Switch { hops: 1 }));
    assert_eq!(run(1.0), (1, 4, Step::Play));
    // Jump from view 1 to view 2 ... and straight back to view 0 across two hops:
    // view 1 frame 4 -> next[4] = 2 in view 2, +1 = 3.
    assert_eq!(run(2.0), (2, 3, Step::Switch { hops: 1 }));
    // view 2 frame 3 -> prev[3] = 2 in view 1 -> prev[2] = 3 in view 0, +1 = 4.
    assert_eq!(run(0.0), (0, 4, Step::Switch { hops: 2 }));
    assert_eq!((p.wraps, p.switches), (1, 4));
}

#[test]
fn split_q_tie_and_integers() {
    let s = |floor, ceil, nearest| QSplit {
        floor,
        ceil,
        nearest,
    };
    assert_eq!(split_q(1.0), s(1, 1, 1));
    assert_eq!(split_q(1.5), s(1, 2, 2));
    assert_eq!(split_q(1.4999999), s(1, 2, 1));
    assert_eq!(split_q(0.0), s(0, 0, 0));
}

#[test]
fn out_of_range_q_is_an_error() {
    let s = tiny();
    let mut p = Player::new();
    for q in [-0.1, 2.0001, f64::NAN, f64::INFINITY] {
        let e = p.advance(&s, q).unwrap_err().to_string();
        assert!(e.contains("[0, 2]"), "{e}");
    }
}

/// The renderer's morph (fixed-point runs, f32 weights, gain) and the reference
/// `parallax::morph` make the same picture: a textured pair whose right half is a nearer
/// plane (6 px of parallax), estimated, then blended at three fractions under plane
/// homographies that move the output.
#[test]
fn renderer_morph_matches_the_reference_morph() {
    let (a, b) = crate::parallax::test_pair();
    let (w, h) = a.dimensions();
    let hab = Homography::translation(-2.0, 0.0);
    let geo = crate::parallax::Geometry::straight([1.0, 0.0], -4, 12);
    let par = crate::parallax::estimate(
        &a,
        &b,
        &hab,
        &geo,
        &crate::parallax::ParallaxParams::default(),
    );
    for f in [0.25, 0.5, 0.75] {
        let h_aq = Homography::translation(-2.0 * f, 0.0);
        let h_bq = Homography::translation(2.0 * (1.0 - f), 0.0);
        let reference = crate::parallax::morph(&a, &b, &par, &h_aq, &h_bq, f, w, h);
        let mut out = RgbImage::new(w, h);
        let (pa, pb) = (Padded::new(&a), Padded::new(&b));
        morph_blend(
            [&pa, &pb],
            &par,
            [&h_aq, &h_bq],
            [[1.0; 3]; 2],
            f,
            &mut out,
            None,
        );
        let diffs: Vec<i32> = out
            .as_raw()
            .iter()
            .zip(reference.as_raw())
            .map(|(&p, &q)| (p as i32 - q as i32).abs())
            .collect();
        let close = diffs.iter().filter(|&&d| d <= 2).count();
        assert!(
            close * 1000 >= 995 * diffs.len(),
            "f = {f}: {close} of {} channel values within 2 levels",
            diffs.len()
        );
    }
}
