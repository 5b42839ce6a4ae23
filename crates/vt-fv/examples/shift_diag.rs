//! Diagnostic: a saved render (or any photo) against a test view's RGBA truth composited over
//! white, as `vt fv eval` scores NeRF data: the squared error split by the truth's alpha
//! (outside the object, its anti-aliased rim, the opaque object), with the opaque pixels' PSNR,
//! then the whole image's PSNR with the render moved by sub-pixel shifts (bilinear), which
//! tells a misregistration of the whole image from errors of its own.
//! `cargo run --release -p vt-fv --example shift_diag -- RENDER.png TRUTH.png [ERROR.png]`
//! (ERROR.png: the per-pixel RMS error, four times amplified).

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: shift_diag RENDER.png TRUTH.png [ERROR.png]");
        std::process::exit(2);
    }
    let render = image::open(&args[1]).unwrap().to_rgb8();
    let truth_rgba = image::open(&args[2]).unwrap().to_rgba8();
    let (w, h) = render.dimensions();
    assert_eq!(
        (w, h),
        truth_rgba.dimensions(),
        "render and truth sizes differ"
    );
    let truth: Vec<[f64; 3]> = truth_rgba
        .pixels()
        .map(|p| {
            let a = p[3] as f64 / 255.0;
            [0, 1, 2].map(|k| p[k] as f64 * a + 255.0 * (1.0 - a))
        })
        .collect();
    let sq =
        |c: [f64; 3], t: [f64; 3]| -> f64 { (0..3).map(|k| ((c[k] - t[k]) / 255.0).powi(2)).sum() };
    // 0: outside (alpha 0), 1: rim, 2: opaque.
    let (mut part, mut count) = ([0.0f64; 3], [0usize; 3]);
    let mut error = image::RgbImage::new(w, h);
    for (i, p) in truth_rgba.pixels().enumerate() {
        let (x, y) = (i as u32 % w, i as u32 / w);
        let e = sq(render.get_pixel(x, y).0.map(f64::from), truth[i]);
        let class = match p[3] {
            0 => 0,
            255 => 2,
            _ => 1,
        };
        part[class] += e;
        count[class] += 1;
        let v = ((e / 3.0).sqrt() * 4.0 * 255.0).min(255.0) as u8;
        error.put_pixel(x, y, image::Rgb([v; 3]));
    }
    let total: f64 = part.iter().sum::<f64>().max(1e-12);
    let share = |k: usize| 100.0 * part[k] / total;
    println!(
        "squared error: outside {:.0}% ({} px), rim {:.0}% ({} px), opaque {:.0}% ({} px, PSNR {:.2} dB)",
        share(0),
        count[0],
        share(1),
        count[1],
        share(2),
        count[2],
        -10.0 * (part[2] / (3.0 * count[2].max(1) as f64)).log10()
    );
    if let Some(path) = args.get(3) {
        error.save(path).unwrap();
    }
    let shifts = [-1.0, -0.5, -0.25, 0.0, 0.25, 0.5, 1.0f64];
    println!(
        "PSNR (dB) with the render moved by dx (columns) and dy (rows), 2 px border left out:"
    );
    println!(
        "   dy \\ dx{}",
        shifts
            .iter()
            .map(|d| format!(" {d:6.2}"))
            .collect::<String>()
    );
    for dy in shifts {
        let mut line = format!("{dy:9.2}");
        for dx in shifts {
            let (mut se, mut n) = (0.0, 0.0);
            for y in 2..h - 2 {
                for x in 2..w - 2 {
                    let c = bilinear(&render, x as f64 + dx, y as f64 + dy);
                    se += sq(c, truth[(y * w + x) as usize]);
                    n += 3.0;
                }
            }
            line += &format!(" {:6.2}", -10.0 * (se / n).log10());
        }
        println!("{line}");
    }
}

/// Bilinear sample at (u, v), inside the image (the 2 px border keeps it there).
fn bilinear(img: &image::RgbImage, u: f64, v: f64) -> [f64; 3] {
    let (x0, y0) = (u.floor(), v.floor());
    let (fx, fy) = (u - x0, v - y0);
    let p = |x: f64, y: f64| img.get_pixel(x as u32, y as u32).0;
    let (a, b, c, d) = (
        p(x0, y0),
        p(x0 + 1.0, y0),
        p(x0, y0 + 1.0),
        p(x0 + 1.0, y0 + 1.0),
    );
    [0, 1, 2].map(|k| {
        (a[k] as f64 * (1.0 - fx) + b[k] as f64 * fx) * (1.0 - fy)
            + (c[k] as f64 * (1.0 - fx) + d[k] as f64 * fx) * fy
    })
}
