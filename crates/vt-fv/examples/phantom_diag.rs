//! What the photos' depth maps say where a test view's coverage errs: for every covered pixel
//! of each test view, the rendered point is classed in every training photo (outside its frame
//! or silhouette, no depth there, on its surface, seen through, hidden behind its surface), and
//! the classes are tallied apart for pixels outside the test photo's silhouette (phantom
//! volume) and inside it (the object).
//!
//! ```sh
//! cargo run --release -p vt-fv --example phantom_diag -- DATA TESTFILE [key=value,...]
//! ```

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::Vector3;
use vt_fv::dataset::{DataOptions, Dataset, ModelParams};
use vt_fv::pipeline::{novel_view_in, ViewParams};

#[path = "common/settings.rs"]
mod settings;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: phantom_diag DATA TESTFILE [key=value,...]");
        std::process::exit(2);
    }
    let dir = Path::new(&args[1]);
    let train = Dataset::load(dir, &DataOptions::default()).unwrap();
    let test = Dataset::load_set(&dir.join(&args[2]), &DataOptions::default()).unwrap();
    let mut view = ViewParams::default();
    let mut m = ModelParams::default();
    settings::apply(args.get(3).map_or("", |s| s.as_str()), &mut view, &mut m);
    let (model, _) = train.build_without(None, &m, &mut |_, _, _| {}).unwrap();
    if model.depths.len() != train.cams.len() {
        eprintln!("phantom_diag: the model has no depth maps (stereo off?)");
        std::process::exit(2);
    }
    let vs = model.grid.voxel_size().min();
    // (inside the truth, class string) -> pixels
    let mut tally: BTreeMap<(bool, String), usize> = BTreeMap::new();
    let (mut phantom, mut object) = (0usize, 0usize);
    // On object pixels: the two nearest photos' depth less the point's depth there, in voxels.
    let mut signed: Vec<f64> = Vec::new();
    let centre = vt_fv::texture::model_centre(&model);
    for (i, cam) in test.cams.iter().enumerate() {
        let (w, h) = test.images[i].dimensions();
        let v = novel_view_in(
            &model,
            &train.cams,
            &train.images,
            Some(&train.masks),
            cam,
            w,
            h,
            &view,
        )
        .unwrap();
        let kinv = cam.k.try_inverse().unwrap();
        let a = cam.r.transpose() * kinv;
        let c = cam.centre();
        let truth = &test.masks[i];
        let near = vt_fv::texture::nearest_by_direction(&train.cams, cam, &centre, 2);
        let mut view_phantom = 0;
        for y in 0..h {
            for x in 0..w {
                let idx = (y * w + x) as usize;
                let d = v.rough.depth[idx] as f64;
                if !v.rough.coverage.get(x, y) || !d.is_finite() {
                    continue;
                }
                let inside = truth.get(x, y);
                let p = c + a * Vector3::new(x as f64, y as f64, 1.0) * d;
                // Per photo: o outside frame/silhouette, n no depth, s on surface, t seen
                // through, b hidden behind the photo's surface.
                let (mut n, mut s, mut t, mut b) = (0, 0, 0, 0);
                if inside {
                    for &k in &near {
                        if let Some((u, vv, z)) = train.cams[k].project(&p) {
                            let dm = model.depths[k].nearest(u, vv) as f64;
                            if dm.is_finite() {
                                signed.push((dm - z) / vs);
                            }
                        }
                    }
                }
                for (k, tc) in train.cams.iter().enumerate() {
                    let Some((u, vv, z)) = tc.project(&p) else {
                        continue;
                    };
                    let (ui, vi) = ((u + 0.5).floor(), (vv + 0.5).floor());
                    let mk = &train.masks[k];
                    if ui < 0.0 || vi < 0.0 || ui >= mk.width() as f64 || vi >= mk.height() as f64 {
                        continue;
                    }
                    if !mk.get(ui as u32, vi as u32) {
                        continue;
                    }
                    let dm = model.depths[k].nearest(u, vv) as f64;
                    if !dm.is_finite() {
                        n += 1;
                    } else if (dm - z).abs() <= 0.75 * vs {
                        s += 1;
                    } else if dm > z + vs {
                        t += 1;
                    } else if dm < z - vs {
                        b += 1;
                    } else {
                        s += 1;
                    }
                }
                let class = format!(
                    "surf{} thru{} nodepth{} hidden{}",
                    s.min(2),
                    t.min(2),
                    n.min(3),
                    b.min(3)
                );
                *tally.entry((inside, class)).or_default() += 1;
                if inside {
                    object += 1;
                } else {
                    phantom += 1;
                    view_phantom += 1;
                }
            }
        }
        println!(
            "{}: phantom {} px, truth {} px",
            cam.name,
            view_phantom,
            truth.count_ones()
        );
    }
    println!("covered outside the truth: {phantom} px; inside: {object} px");
    signed.sort_by(f64::total_cmp);
    let q = |f: f64| signed[((signed.len() - 1) as f64 * f) as usize];
    println!(
        "object pixels, the two nearest photos' depth less the point's (voxels, {} samples): 10 % {:.2}, 25 % {:.2}, median {:.2}, 75 % {:.2}, 90 % {:.2}",
        signed.len(), q(0.1), q(0.25), q(0.5), q(0.75), q(0.9)
    );
    // Each class's share of the phantom pixels beside its share of the object's: a rule that
    // uncovers a class takes both.
    let mut classes: Vec<&String> = tally.keys().map(|(_, c)| c).collect();
    classes.sort();
    classes.dedup();
    let share = |inside: bool, c: &String, total: usize| {
        100.0 * tally.get(&(inside, c.clone())).copied().unwrap_or(0) as f64 / total.max(1) as f64
    };
    classes.sort_by(|a, b| share(false, b, phantom).total_cmp(&share(false, a, phantom)));
    println!("{:40} {:>9} {:>9}", "class", "phantom %", "object %");
    for c in classes.iter().take(15) {
        println!(
            "{c:40} {:9.1} {:9.1}",
            share(false, c, phantom),
            share(true, c, object)
        );
    }
    // The simplest rules over the classes: what each would uncover of either.
    for (rule, test) in [
        (
            "no photo puts it on a surface",
            (|c: &str| c.starts_with("surf0")) as fn(&str) -> bool,
        ),
        ("... and some photo sees through it", |c: &str| {
            c.starts_with("surf0") && !c.contains("thru0")
        }),
        ("... and no photo without a depth there", |c: &str| {
            c.starts_with("surf0") && !c.contains("thru0") && c.contains("nodepth0")
        }),
    ] {
        let take = |inside: bool, total: usize| {
            tally
                .iter()
                .filter(|((i, c), _)| *i == inside && test(c))
                .map(|(_, n)| *n)
                .sum::<usize>() as f64
                * 100.0
                / total.max(1) as f64
        };
        println!(
            "{rule:40} phantom {:5.1} %, object {:5.1} % ({:.0} px against {:.0})",
            take(false, phantom),
            take(true, object),
            take(false, phantom) * phantom as f64 / 100.0,
            take(true, object) * object as f64 / 100.0
        );
    }
}
