//! Middlebury line scenes (issue #33): `vt analyze` (the release binary beside this example) on
//! the even views, with and without testdata's points, each render at q = 0.5, 1.5, 2.5 scored
//! against the odd views. `mb_eval [SCENE..] [-- extra analyze args]`.

use std::path::{Path, PathBuf};
use std::process::Command;

use image::RgbImage;
use vt_core::render::{Player, RenderParams, Renderer};
use vt_io::scene::LoadedScene;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let split = args.iter().position(|a| a == "--").unwrap_or(args.len());
    let mut scenes: Vec<String> = args[..split].to_vec();
    let extra: Vec<String> = args
        .get(split + 1..)
        .map(|a| a.to_vec())
        .unwrap_or_default();
    if scenes.is_empty() {
        scenes = vec!["Dolls".into(), "Moebius".into(), "Reindeer".into()];
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/middlebury-line");
    let vt = std::env::current_exe()
        .unwrap()
        .parent()
        .unwrap()
        .join("../vt");
    let tmp = tempfile::tempdir().unwrap();
    for scene in &scenes {
        let dir = root.join(scene);
        let views: Vec<PathBuf> = [0, 2, 4, 6]
            .iter()
            .map(|&k| {
                let d = tmp.path().join(format!("{scene}-v{k}"));
                std::fs::create_dir(&d).unwrap();
                for i in 0..8 {
                    std::fs::copy(
                        dir.join(format!("view{k}.png")),
                        d.join(format!("{i:02}.png")),
                    )
                    .unwrap();
                }
                d
            })
            .collect();
        let points = dir.join("points_0246.txt");
        let mut line = format!("{scene:9}");
        for (name, pts) in [("auto", false), ("points", true)] {
            let out = tmp.path().join(format!("{scene}-{name}"));
            let mut cmd = Command::new(&vt);
            cmd.arg("analyze")
                .args(&views)
                .args(["--min-length", "4", "--out"])
                .arg(&out);
            if pts {
                cmd.arg("--points").arg(&points);
            }
            cmd.args(&extra);
            let o = cmd.output().unwrap();
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            let sc = LoadedScene::open(&out).unwrap();
            let mut ps = Vec::new();
            for (i, q) in [0.5, 1.5, 2.5].into_iter().enumerate() {
                let truth = image::open(dir.join(format!("view{}.png", 2 * i + 1)))
                    .unwrap()
                    .to_rgb8();
                let choice = Player::new().advance(&sc.render, q).unwrap();
                let mut r = Renderer::new(sc.render.clone(), RenderParams::default()).unwrap();
                let (w, h) = r.size();
                let mut img = RgbImage::new(w, h);
                r.render_into(&sc.objects, q, &choice, &mut img).unwrap();
                if std::env::var_os("SAVE").is_some() {
                    img.save(format!("/tmp/mb-{scene}-{name}-{q}.png")).unwrap();
                }
                ps.push(vt_core::metrics::psnr(&img, &truth, None).unwrap());
            }
            let mean = ps.iter().sum::<f64>() / 3.0;
            line += &format!(
                "  {name}: {mean:.2} ({:.2} {:.2} {:.2})",
                ps[0], ps[1], ps[2]
            );
            if std::env::var_os("KEEP").is_some() {
                let keep = PathBuf::from(format!("/tmp/mb-{scene}-{name}"));
                let _ = std::fs::remove_dir_all(&keep);
                Command::new("cp")
                    .arg("-r")
                    .arg(&out)
                    .arg(&keep)
                    .status()
                    .unwrap();
            }
        }
        println!("{line}");
    }
}
