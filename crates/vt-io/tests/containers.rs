//! Videos as phones and cameras write them (issue #37): each quirk of the container made from
//! tree.avi by ffmpeg, read through `ViewSource`, with its expected outcome. The independent
//! truth is the coded frames themselves (the same stream without the quirk: a quarter turn of
//! them must match exactly) and ffmpeg's own transcode of the quirky file (the clip turned by
//! ffmpeg beforehand), losslessly encoded so that nothing but the quirk differs.

use std::path::{Path, PathBuf};
use std::process::Command;

use image::RgbImage;
use vt_io::frames::ViewSource;

fn tree() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/tree.avi")
}

/// Runs ffmpeg with `args` (quiet, overwriting), panicking with its message on failure.
fn ffmpeg(args: &[&str]) {
    let out = Command::new("ffmpeg")
        .args(["-v", "error", "-y", "-nostdin"])
        .args(args)
        .output()
        .expect("ffmpeg runs");
    assert!(
        out.status.success(),
        "ffmpeg {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Every frame of `path` through vt, with the notes and the size.
fn read(path: &Path) -> vt_io::Result<(Vec<RgbImage>, Vec<String>)> {
    let mut src = ViewSource::open(path)?;
    let notes = src.notes();
    let frames = src.read_all()?;
    for f in &frames {
        assert_eq!(
            f.dimensions(),
            src.size(),
            "a frame of another size than the source's"
        );
    }
    Ok((frames, notes))
}

/// Mean and largest absolute difference over all channels of two same-size frame lists.
fn diff(a: &[RgbImage], b: &[RgbImage]) -> (f64, u8) {
    assert_eq!(a.len(), b.len(), "frame counts");
    let (mut sum, mut n, mut max) = (0u64, 0u64, 0u8);
    for (x, y) in a.iter().zip(b) {
        assert_eq!(x.dimensions(), y.dimensions());
        for (p, q) in x.as_raw().iter().zip(y.as_raw()) {
            let d = p.abs_diff(*q);
            sum += d as u64;
            n += 1;
            max = max.max(d);
        }
    }
    (sum as f64 / n as f64, max)
}

#[test]
fn container_quirks_give_what_a_player_shows_or_a_clear_refusal() {
    if !vt_io::video::ffmpeg_available() {
        eprintln!("skipped: the quirky clips are made and read by ffmpeg, which is not installed");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let p = |name: &str| dir.join(name);
    // The plain clip: 6 frames of tree.avi, lossless 4:2:0 H.264 (what every quirk starts from).
    let lossless = ["-c:v", "libx264", "-qp", "0", "-pix_fmt", "yuv420p"];
    let base = p("base.mp4");
    ffmpeg(
        &[
            &["-i", s(&tree()), "-frames:v", "6"][..],
            &lossless,
            &[s(&base)],
        ]
        .concat(),
    );
    let (coded, notes) = read(&base).unwrap();
    assert_eq!(coded[0].dimensions(), (320, 240));
    assert!(notes.is_empty(), "{notes:?}");

    // Display rotations, as phones write portrait clips: the same stream, a rotation in the
    // container. The frames are the coded ones turned (exactly), the size swapped, and equal to
    // the clip ffmpeg turns itself beforehand (which a plain read then takes as it is).
    for rotate in ["90", "270", "180"] {
        let clip = p(&format!("rotate{rotate}.mp4"));
        ffmpeg(&[
            "-i",
            s(&base),
            "-c",
            "copy",
            "-metadata:s:v:0",
            &format!("rotate={rotate}"),
            s(&clip),
        ]);
        let (frames, notes) = read(&clip).unwrap();
        let want = if rotate == "180" {
            (320, 240)
        } else {
            (240, 320)
        };
        assert_eq!(frames[0].dimensions(), want, "rotate={rotate}");
        assert!(
            notes.iter().any(|n| n.contains("display rotation")),
            "rotate={rotate}: {notes:?}"
        );
        let turns: [fn(&RgbImage) -> RgbImage; 3] = [
            image::imageops::rotate90,
            image::imageops::rotate180,
            image::imageops::rotate270,
        ];
        let exact = turns.iter().any(|turn| {
            let turned: Vec<RgbImage> = coded.iter().map(turn).collect();
            turned[0].dimensions() == want && diff(&turned, &frames).1 == 0
        });
        assert!(exact, "rotate={rotate}: not a turn of the coded frames");
        let by_ffmpeg = p(&format!("turned{rotate}.mp4"));
        ffmpeg(&[&["-i", s(&clip)][..], &lossless, &[s(&by_ffmpeg)]].concat());
        let (turned, notes) = read(&by_ffmpeg).unwrap();
        assert!(notes.is_empty(), "{notes:?}");
        let (mean, max) = diff(&turned, &frames);
        assert!(
            max <= 1,
            "rotate={rotate}: {mean:.3} mean, {max} max from ffmpeg's turn"
        );
    }

    // Non-square pixels (2:1, as anamorphic cameras write): resampled to square, twice as wide;
    // averaging column pairs gives the coded frames back within the resampling's error.
    let wide = p("sar2.mp4");
    ffmpeg(
        &[
            &["-i", s(&base), "-vf", "setsar=2/1"][..],
            &lossless,
            &[s(&wide)],
        ]
        .concat(),
    );
    let (frames, notes) = read(&wide).unwrap();
    assert_eq!(frames[0].dimensions(), (640, 240));
    assert!(
        notes.iter().any(|n| n.contains("pixel aspect 2:1")),
        "{notes:?}"
    );
    let halved: Vec<RgbImage> = frames
        .iter()
        .map(|f| {
            RgbImage::from_fn(320, 240, |x, y| {
                let (a, b) = (f.get_pixel(2 * x, y), f.get_pixel(2 * x + 1, y));
                image::Rgb(std::array::from_fn(|c| {
                    (a[c] as u16 + b[c] as u16).div_ceil(2) as u8
                }))
            })
        })
        .collect();
    let (mean, _) = diff(&halved, &coded);
    assert!(
        mean < 2.0,
        "2:1 pixels: {mean:.2} grey levels from the coded frames"
    );

    // 10-bit 4:2:0 (phones' HDR and HEVC clips): read through ffmpeg's RGB conversion, whose
    // chroma upsampling (swscale's bicubic) differs from vt's own 4:2:0 conversion of the 8-bit
    // stream by a grey level or two at colour edges (1.7 on average here).
    let ten = p("10bit.mp4");
    ffmpeg(
        &[
            &["-i", s(&base), "-c:v", "libx264", "-qp", "0"][..],
            &["-pix_fmt", "yuv420p10le", s(&ten)],
        ]
        .concat(),
    );
    let (frames, notes) = read(&ten).unwrap();
    assert!(notes.is_empty(), "{notes:?}");
    let (mean, _) = diff(&frames, &coded);
    assert!(
        mean < 2.5,
        "10-bit: {mean:.2} grey levels from the 8-bit frames"
    );

    // Odd sizes (no 4:2:0 form): read as RGB at their own size.
    let odd = p("odd.mkv");
    ffmpeg(&[
        "-i",
        s(&base),
        "-vf",
        "scale=321:241",
        "-c:v",
        "ffv1",
        s(&odd),
    ]);
    let (frames, _) = read(&odd).unwrap();
    assert_eq!((frames.len(), frames[0].dimensions()), (6, (321, 241)));

    // Interlaced (camcorders, broadcast): deinterlaced one frame per frame.
    let fields = p("interlaced.mp4");
    ffmpeg(
        &[
            &[
                "-i",
                s(&base),
                "-flags",
                "+ildct+ilme",
                "-x264opts",
                "tff=1",
            ][..],
            &lossless,
            &[s(&fields)],
        ]
        .concat(),
    );
    let (frames, notes) = read(&fields).unwrap();
    assert_eq!((frames.len(), frames[0].dimensions()), (6, (320, 240)));
    assert!(
        notes.iter().any(|n| n.contains("deinterlaced")),
        "{notes:?}"
    );

    // Refused with one line naming the file: a rotation no quarter turn gives, a truncated
    // file, and two streams of different sizes joined into one.
    let tilted = p("rotate45.mp4");
    ffmpeg(&[
        "-i",
        s(&base),
        "-c",
        "copy",
        "-metadata:s:v:0",
        "rotate=45",
        s(&tilted),
    ]);
    let e = read(&tilted).map(|_| ()).unwrap_err().to_string();
    eprintln!("rotation 45: {e}");
    assert!(
        e.contains("rotate45.mp4") && e.contains("not a multiple of 90"),
        "{e}"
    );
    let whole = p("faststart.mp4");
    ffmpeg(&[
        "-i",
        s(&base),
        "-c",
        "copy",
        "-movflags",
        "+faststart",
        s(&whole),
    ]);
    let bytes = std::fs::read(&whole).unwrap();
    let cut = p("truncated.mp4");
    std::fs::write(&cut, &bytes[..bytes.len() * 6 / 10]).unwrap();
    let e = read(&cut).map(|_| ()).unwrap_err().to_string();
    eprintln!("truncated: {e}");
    assert!(e.contains("truncated.mp4"), "{e}");
    let (a, b) = (p("a.ts"), p("b.ts"));
    ffmpeg(&["-i", s(&base), "-c:v", "libx264", s(&a)]);
    ffmpeg(&[
        "-i",
        s(&base),
        "-vf",
        "scale=240:320",
        "-c:v",
        "libx264",
        s(&b),
    ]);
    // (Transport-stream bytes under a name vt takes as a video: ffmpeg reads by content.)
    let joined = p("joined.mkv");
    let mut both = std::fs::read(&a).unwrap();
    both.extend(std::fs::read(&b).unwrap());
    std::fs::write(&joined, both).unwrap();
    let e = read(&joined).map(|_| ()).unwrap_err().to_string();
    eprintln!("joined: {e}");
    assert!(e.contains("joined.mkv") && !e.contains("not a view"), "{e}");
}
