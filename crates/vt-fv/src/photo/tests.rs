use super::*;

#[test]
fn footprint_holds_the_centre_pixel() {
    let s = Splat {
        u: 10.4,
        v: 3.6,
        z: 1.0,
        half: 0.1,
    };
    assert_eq!(footprint(&s, 20, 20), Some((10, 4, 10, 4)));
    let s = Splat {
        u: 10.0,
        v: 3.0,
        z: 1.0,
        half: 1.5,
    };
    assert_eq!(footprint(&s, 20, 20), Some((9, 2, 11, 4)));
    let s = Splat {
        u: -3.0,
        v: 3.0,
        z: 1.0,
        half: 1.5,
    };
    assert_eq!(footprint(&s, 20, 20), None);
}
#[test]
fn agree_leaves_the_farthest_samples_out() {
    let good = [[100.0, 50.0, 20.0], [104.0, 52.0, 18.0], [97.0, 49.0, 22.0]];
    let mut five = good.to_vec();
    five.push([101.0, 51.0, 20.0]);
    five.push([230.0, 50.0, 20.0]);
    let paper = Stats::judge(&five, 15.0, Consistency::StdDev);
    assert!(!paper.consistent && paper.n == 5);
    // 0.8 of 5 keeps 4: the outlier goes, the rest agree; the colour is theirs.
    let agree = Stats::judge(&five, 15.0, Consistency::Agree(0.8));
    assert!(agree.consistent && agree.n == 5, "{:?}", agree.colour);
    assert_eq!(agree.colour, [101, 51, 20]);
    // Two outliers out of five are one too many for 0.8, not for 0.6.
    five[3] = [20.0, 200.0, 20.0];
    assert!(!Stats::judge(&five, 15.0, Consistency::Agree(0.8)).consistent);
    assert!(Stats::judge(&five, 15.0, Consistency::Agree(0.6)).consistent);
    // At least two samples are always judged: two that disagree stay inconsistent.
    let two = [[0.0; 3], [100.0; 3]];
    for rule in [Consistency::StdDev, Consistency::Agree(0.0)] {
        assert!(!Stats::judge(&two, 15.0, rule).consistent);
        assert!(Stats::judge(&two[..1], 15.0, rule).consistent);
        assert!(Stats::judge(&[], 15.0, rule).consistent);
    }
}

#[test]
fn agree_from_applies_only_with_enough_judges() {
    let rule = Consistency::AgreeFrom { share: 0.8, min: 6 };
    // Five samples, one far off: too few judges, the paper's rule carves.
    let mut samples = vec![[100.0, 50.0, 20.0]; 4];
    samples.push([230.0, 50.0, 20.0]);
    assert!(!Stats::judge(&samples, 15.0, rule).consistent);
    // Ten, one far off: the outlier is left out, the rest agree.
    let mut ten = vec![[100.0, 50.0, 20.0]; 9];
    ten.push([230.0, 50.0, 20.0]);
    let v = Stats::judge(&ten, 15.0, rule);
    assert!(v.consistent && v.n == 10);
    assert!(!Stats::judge(&ten, 15.0, Consistency::StdDev).consistent);
}

/// A surface voxel's index, colour and number of cameras seeing it.
type Coloured = (usize, [u8; 3], u32);

/// The reference algorithm: every pass re-renders every ID buffer from scratch and
/// re-tests every surface voxel.
fn photo_hull_naive(
    mut grid: VoxelGrid,
    cams: &[Camera],
    images: &[RgbImage],
    p: &PhotoParams,
) -> (VoxelGrid, Vec<Coloured>, usize) {
    let vs = grid.voxel_size();
    let size = (vs.x * vs.y * vs.z).cbrt();
    let mut surface = surface_of(&grid);
    let mut listed: std::collections::HashSet<usize> = surface.iter().copied().collect();
    let mut passes = 0;
    loop {
        let centres: Vec<Vector3<f64>> = surface
            .iter()
            .map(|&i| grid.centre(grid.coords(i)))
            .collect();
        let bufs: Vec<IdBuffer> = cams
            .iter()
            .zip(images)
            .map(|(cam, img)| {
                let mut b = IdBuffer::new(cam, img.width(), img.height());
                for (slot, c) in centres.iter().enumerate() {
                    b.add(cam, slot as u32, c, size, p.splat_scale);
                }
                b.refresh(
                    cam,
                    &centres,
                    &vec![true; centres.len()],
                    size,
                    p.splat_scale,
                    &mut Vec::new(),
                );
                b
            })
            .collect();
        let slots: Vec<u32> = (0..surface.len() as u32).collect();
        let st = gather(cams, images, &bufs, &centres, &slots, size, p);
        let bad: Vec<usize> = (0..surface.len()).filter(|&k| !st[k].consistent).collect();
        if bad.is_empty() || passes >= p.max_passes {
            let mut out: Vec<Coloured> = surface
                .iter()
                .zip(&st)
                .map(|(&i, s)| (i, s.colour, s.n))
                .collect();
            out.sort_unstable_by_key(|v| v.0);
            return (grid, out, passes);
        }
        passes += 1;
        for &k in &bad {
            grid.set_index(surface[k], false);
        }
        let mut next: Vec<usize> = surface
            .iter()
            .copied()
            .filter(|&i| grid.get_index(i))
            .collect();
        for &k in &bad {
            let [x, y, z] = grid.coords(surface[k]).map(|c| c as i64);
            for (dx, dy, dz) in [
                (-1, 0, 0),
                (1, 0, 0),
                (0, -1, 0),
                (0, 1, 0),
                (0, 0, -1),
                (0, 0, 1),
            ] {
                if grid.get(x + dx, y + dy, z + dz) {
                    let j = grid.index((x + dx) as usize, (y + dy) as usize, (z + dz) as usize);
                    if listed.insert(j) {
                        next.push(j);
                    }
                }
            }
        }
        surface = next;
    }
}

#[test]
fn incremental_passes_match_full_re_renders() {
    let d = vt_synth::object::generate(&vt_synth::object::SceneParams {
        n_views: 6,
        width: 120,
        height: 120,
        extra_angles_deg: vec![],
        ..Default::default()
    })
    .unwrap()
    .try_map_cameras(|c| crate::Camera::new(c.name.clone(), c.k, c.r, c.t))
    .unwrap();
    let vh = crate::hull::visual_hull(
        &d.cameras,
        &d.masks,
        &crate::hull::HullParams {
            dims: [48; 3],
            ..Default::default()
        },
    )
    .unwrap();
    for p in [
        PhotoParams::default(),
        PhotoParams {
            threshold: 8.0,
            max_passes: 5,
            ..Default::default()
        },
        PhotoParams {
            visibility: Visibility::Footprint(0.25),
            consistency: Consistency::Agree(0.8),
            colour_partly_seen: false,
            ..Default::default()
        },
    ] {
        let (g, naive, passes) = photo_hull_naive(vh.clone(), &d.cameras, &d.photos, &p);
        let m = photo_hull(vh.clone(), &d.cameras, &d.photos, &p, &mut |_, _, _| {}).unwrap();
        assert!(
            passes > 1,
            "{p:?}: carving too easy to test ({passes} passes)"
        );
        assert_eq!(m.passes, passes, "{p:?}");
        assert!(m.grid == g, "{p:?}: occupancy differs");
        let inc: Vec<Coloured> = m
            .surface
            .iter()
            .filter(|v| v.seen_by > 0)
            .map(|v| (v.index, v.colour, v.seen_by))
            .collect();
        let naive_seen: Vec<_> = naive.into_iter().filter(|v| v.2 > 0).collect();
        assert_eq!(inc, naive_seen, "{p:?}: seen surface voxels differ");
    }
}
