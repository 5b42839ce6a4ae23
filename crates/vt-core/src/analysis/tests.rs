use super::*;

/// A tiny two-view scene: a square moving with period 10 over a gradient, view 1 shifted 5 px.
fn view(shift: u32, offset: usize, n: usize) -> MemorySource {
    let frames = (0..n)
        .map(|f| {
            let ph = ((f + offset) % 10) as f64 / 10.0 * std::f64::consts::TAU;
            let cx = 20.0 + 8.0 * ph.sin() + shift as f64;
            let cy = 16.0 + 6.0 * ph.cos();
            RgbImage::from_fn(48, 32, |x, y| {
                let inside = (x as f64 - cx).abs() < 4.0 && (y as f64 - cy).abs() < 4.0;
                if inside {
                    image::Rgb([250, 20, 20])
                } else {
                    image::Rgb([(x * 3) as u8, (y * 5) as u8, 90])
                }
            })
        })
        .collect();
    MemorySource {
        name: format!("mem{shift}"),
        frames,
    }
}

#[test]
fn two_view_scene_end_to_end() {
    let (mut a, mut b) = (view(0, 0, 40), view(5, 3, 40));
    let pts = |dx: f64| {
        vec![
            Point::new(2.0 + dx, 2.0),
            Point::new(40.0 + dx, 3.0),
            Point::new(41.0 + dx, 30.0),
            Point::new(3.0 + dx, 29.0),
        ]
    };
    let params = AnalyzeParams {
        loops: LoopParams {
            window: 3,
            min_length: 15,
        },
        ..Default::default()
    };
    let res = analyze(
        &mut [&mut a, &mut b],
        &[pts(0.0), pts(5.0)],
        &params,
        &mut Quiet,
    )
    .unwrap();
    assert_eq!(res.model(), Some(MotionModel::Translation));
    // Streaming (no frame cache) gives exactly the same analysis.
    let (mut a2, mut b2) = (view(0, 0, 40), view(5, 3, 40));
    let streamed = AnalyzeParams {
        cache_bytes: 0,
        ..params
    };
    let res2 = analyze(
        &mut [&mut a2, &mut b2],
        &[pts(0.0), pts(5.0)],
        &streamed,
        &mut Quiet,
    )
    .unwrap();
    for (x, y) in res.views.iter().zip(&res2.views) {
        assert_eq!(x.background, y.background);
        assert_eq!(x.masks, y.masks);
        assert_eq!(x.best_loop, y.best_loop);
    }
    assert_eq!(res.links[0].to_next, res2.links[0].to_next);
    for v in &res.views {
        assert_eq!(v.best_loop.len() % 10, 0);
        assert_eq!(v.best_loop.cost, 0);
    }
    // Frame s of view 0 has phase s; frame t of view 1 has phase t + 3.
    for (s, t) in res.links[0].to_next.iter().enumerate() {
        assert_eq!((t.unwrap() + 3) % 10, s % 10);
    }
    for (s, t) in res.links[0].to_prev.iter().enumerate() {
        assert_eq!(t.unwrap() % 10, (s + 3) % 10);
    }
}

#[test]
fn views_of_different_sizes_are_named() {
    let mut a = view(0, 0, 20);
    let mut b = MemorySource {
        name: "small".into(),
        frames: vec![RgbImage::new(10, 10); 20],
    };
    let params = AnalyzeParams {
        loops: LoopParams {
            window: 2,
            min_length: 5,
        },
        ..Default::default()
    };
    let pts = vec![
        Point::new(0.0, 0.0),
        Point::new(9.0, 0.0),
        Point::new(9.0, 9.0),
        Point::new(0.0, 9.0),
    ];
    let err = analyze(
        &mut [&mut a, &mut b],
        &[pts.clone(), pts],
        &params,
        &mut Quiet,
    )
    .unwrap_err();
    assert_eq!(
        err.to_string(),
        "views have different sizes: view 0 is 48x32, view 1 (small) is 10x10"
    );
}

/// Several views, one steadied: every view is cropped to the smallest area any keeps, centred
/// in its own; with none steadied nothing is cropped.
#[test]
fn steadied_views_share_one_crop_size() {
    use crate::stabilize::{Crop, Shake, Verdict};
    let shake = |verdict, area: Crop| Shake {
        name: "v".into(),
        frames: 2,
        size: (100, 80),
        verdict,
        model: None,
        maps: vec![crate::Homography::identity(); 2],
        largest_px: 0.0,
        largest_deg: 0.0,
        area,
        registered: (0, 0.0),
    };
    let full = Crop {
        x: 0,
        y: 0,
        width: 100,
        height: 80,
    };
    let kept = Crop {
        x: 3,
        y: 5,
        width: 90,
        height: 70,
    };
    let crops = view_crops(&[shake(Verdict::Still, full), shake(Verdict::Steadied, kept)]).unwrap();
    assert_eq!(
        crops,
        vec![
            Some(Crop {
                x: 5,
                y: 5,
                width: 90,
                height: 70
            }),
            Some(kept)
        ]
    );
    let none = view_crops(&[
        shake(Verdict::Still, full),
        shake(Verdict::Untextured, full),
    ]);
    assert_eq!(none.unwrap(), vec![None, None]);
    // Views of different sizes are named, not cropped to fit.
    let mut other = shake(Verdict::Steadied, kept);
    other.size = (120, 80);
    let e = view_crops(&[shake(Verdict::Still, full), other]).unwrap_err();
    assert!(e.to_string().contains("made still"), "{e}");
}
