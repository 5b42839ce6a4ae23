//! How a player shows a video stream, beyond its coded frames: the display rotation phones
//! write for portrait clips, non-square pixels, interlaced fields. vt analyses what a player
//! shows, so the frames ffmpeg decodes for it are turned (ffmpeg's own autorotation, as players
//! do), resampled to square pixels and deinterlaced; and before a frame is read, the size they
//! decode to is measured and checked against the size the stream's header predicts, so frames
//! are never read with another shape than they have (a portrait clip read as landscape rows is
//! noise in stripes).

use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};

use crate::{Error, Result};

/// What the container says about showing the stream, from `ffprobe`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Display {
    /// Display rotation in degrees as ffprobe reports it, normalised to 0, 90, 180 or 270
    /// (other angles are refused on probing).
    pub rotation: u32,
    /// Sample (pixel) aspect ratio, width over height of one coded pixel; (1, 1) when square
    /// or unknown.
    pub sar: (u32, u32),
    /// Coded as interlaced fields.
    pub interlaced: bool,
}

/// The `ffprobe -show_entries` this module reads.
pub const PROBE_ENTRIES: &str =
    "stream=sample_aspect_ratio,field_order:stream_side_data=rotation:stream_tags=rotate";

impl Display {
    /// Reads the fields of [`PROBE_ENTRIES`] through `field` (the value of `key=` in ffprobe's
    /// output). A rotation that is not a multiple of 90 degrees is refused.
    pub fn from_probe<'a>(path: &Path, field: impl Fn(&str) -> Option<&'a str>) -> Result<Self> {
        // The display matrix's rotation (side data); a `rotate` tag where a demuxer leaves
        // one (ffprobe reports a file's tag 90 as rotation 90: the same number).
        let tag = field("rotate").or_else(|| field("TAG:rotate"));
        let degrees = match (field("rotation"), tag) {
            (Some(r), _) => r.parse::<f64>().ok(),
            (None, Some(t)) => t.parse::<f64>().ok(),
            (None, None) => Some(0.0),
        };
        let rotation = degrees
            .filter(|d| d.is_finite())
            .map(|d| d.rem_euclid(360.0))
            .filter(|d| (d / 90.0 - (d / 90.0).round()).abs() < 1e-6)
            .map(|d| (d.round() as u32) % 360)
            .ok_or_else(|| Error::Video {
                path: path.to_path_buf(),
                message: format!(
                    "display rotation {} is not a multiple of 90 degrees: turn the video \
                     beforehand (ffmpeg -i IN -vf rotate=... OUT)",
                    field("rotation").or(tag).unwrap_or("?")
                ),
            })?;
        let sar = field("sample_aspect_ratio")
            .and_then(|s| {
                let (n, d) = s.split_once(':')?;
                Some((n.parse::<u32>().ok()?, d.parse::<u32>().ok()?))
            })
            .filter(|&(n, d)| n > 0 && d > 0 && n != d)
            .map(|(n, d)| {
                let g = gcd(n, d);
                (n / g, d / g)
            })
            .unwrap_or((1, 1));
        let interlaced = matches!(field("field_order"), Some("tt" | "bb" | "tb" | "bt"));
        Ok(Self {
            rotation,
            sar,
            interlaced,
        })
    }

    /// True when frames decode as coded: no rotation, square pixels, progressive.
    pub fn is_plain(&self) -> bool {
        self.rotation == 0 && self.sar == (1, 1) && !self.interlaced
    }

    /// The `-vf` chain after ffmpeg's autorotation: deinterlacing (one frame per frame), then
    /// square pixels by widening or narrowing the picture (after a quarter turn the filter's
    /// own `sar` is the turned one, so the expression scales the right axis either way).
    pub fn filters(&self) -> Option<String> {
        let mut chain = Vec::new();
        if self.interlaced {
            chain.push("yadif=mode=send_frame:parity=auto:deint=all".to_string());
        }
        if self.sar != (1, 1) {
            chain.push("scale=w=trunc(iw*sar+0.5):h=ih,setsar=1".to_string());
        }
        (!chain.is_empty()).then(|| chain.join(","))
    }

    /// The size frames coded at `coded` decode to through [`Display::filters`] and ffmpeg's
    /// autorotation.
    pub fn shown_size(&self, (w, h): (u32, u32)) -> (u32, u32) {
        let (n, d) = self.sar;
        let turned = self.rotation % 180 == 90;
        // After a quarter turn the picture is h x w and its pixels' aspect d:n.
        let (w, h, n, d) = if turned { (h, w, d, n) } else { (w, h, n, d) };
        let w = ((w as f64 * n as f64 / d as f64) + 0.5).floor() as u32;
        (w, h)
    }

    /// What decoding does beyond reading the frames, in words (empty when nothing).
    pub fn describe(&self, coded: (u32, u32)) -> Vec<String> {
        let mut out = Vec::new();
        let shown = self.shown_size(coded);
        if self.rotation != 0 {
            out.push(format!(
                "display rotation {} degrees: frames turned as a player shows them",
                self.rotation
            ));
        }
        if self.sar != (1, 1) {
            out.push(format!(
                "pixel aspect {}:{}: resampled to square pixels",
                self.sar.0, self.sar.1
            ));
        }
        if self.interlaced {
            out.push("interlaced: deinterlaced (yadif, a frame per frame)".into());
        }
        if !out.is_empty() {
            out.push(format!(
                "{}x{} coded, {}x{} analysed",
                coded.0, coded.1, shown.0, shown.1
            ));
        }
        out
    }
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// The size of the first frame ffmpeg decodes from `path` through `filters`, read from a PPM
/// header (the decode's own output, so what every later read of raw frames will have).
pub fn first_frame_size(path: &Path, filters: Option<&str>) -> Result<(u32, u32)> {
    let err = |message: String| Error::Video {
        path: path.to_path_buf(),
        message,
    };
    let mut cmd = Command::new("ffmpeg");
    cmd.args(["-v", "error", "-nostdin", "-i"])
        .arg(path)
        .args(["-map", "0:v:0", "-frames:v", "1"]);
    if let Some(f) = filters {
        cmd.args(["-vf", f]);
    }
    let mut child = cmd
        .args(["-f", "image2pipe", "-c:v", "ppm", "-"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| err(format!("cannot run ffmpeg: {e}")))?;
    let stderr = crate::video::drain(child.stderr.take().expect("stderr was piped"));
    // "P6\n<w> <h>\n255\n": the header is at most a few dozen bytes.
    let mut head = Vec::new();
    let mut stdout = child.stdout.take().expect("stdout was piped");
    let mut byte = [0u8; 1];
    let mut lines = 0;
    while lines < 3 && head.len() < 64 {
        match stdout.read(&mut byte) {
            Ok(1) => {
                head.push(byte[0]);
                if byte[0] == b'\n' {
                    lines += 1;
                }
            }
            _ => break,
        }
    }
    drop(stdout);
    let _ = child.kill();
    let _ = child.wait();
    let message = stderr.join().unwrap_or_default();
    let text = String::from_utf8_lossy(&head);
    let mut words = text.split_whitespace();
    match (
        words.next(),
        words.next().and_then(|w| w.parse::<u32>().ok()),
        words.next().and_then(|h| h.parse::<u32>().ok()),
    ) {
        (Some("P6"), Some(w), Some(h)) if w > 0 && h > 0 => Ok((w, h)),
        _ => Err(err(format!(
            "not a readable video (no frame decodes: {})",
            message
                .lines()
                .map(str::trim)
                .rfind(|l| !l.is_empty())
                .unwrap_or("ffmpeg gave no frame")
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn probe(pairs: &[(&'static str, &'static str)]) -> Result<Display> {
        Display::from_probe(Path::new("clip.mp4"), |k| {
            pairs.iter().find(|(key, _)| *key == k).map(|(_, v)| *v)
        })
    }

    #[test]
    fn rotations_from_side_data_or_tag() {
        assert_eq!(probe(&[("rotation", "90")]).unwrap().rotation, 90);
        assert_eq!(probe(&[("rotation", "-90")]).unwrap().rotation, 270);
        assert_eq!(probe(&[("rotation", "180")]).unwrap().rotation, 180);
        assert_eq!(probe(&[("rotate", "90")]).unwrap().rotation, 90);
        // ffprobe's default writer prints a tag as TAG:key.
        assert_eq!(probe(&[("TAG:rotate", "270")]).unwrap().rotation, 270);
        assert_eq!(probe(&[]).unwrap().rotation, 0);
        let e = probe(&[("rotation", "45")]).unwrap_err().to_string();
        assert!(e.contains("clip.mp4") && e.contains("45"), "{e}");
    }

    #[test]
    fn shown_sizes() {
        let d = |rotation, sar| Display {
            rotation,
            sar,
            interlaced: false,
        };
        assert_eq!(d(0, (1, 1)).shown_size((320, 240)), (320, 240));
        assert_eq!(d(90, (1, 1)).shown_size((320, 240)), (240, 320));
        assert_eq!(d(270, (1, 1)).shown_size((321, 241)), (241, 321));
        assert_eq!(d(180, (1, 1)).shown_size((320, 240)), (320, 240));
        assert_eq!(d(0, (2, 1)).shown_size((320, 240)), (640, 240));
        assert_eq!(d(0, (8, 9)).shown_size((720, 480)), (640, 480));
        // A quarter turn, then the turned pixels (1:2) made square along the new width.
        assert_eq!(d(90, (2, 1)).shown_size((320, 240)), (120, 320));
        assert!(d(0, (1, 1)).is_plain() && d(0, (1, 1)).filters().is_none());
        assert!(probe(&[("sample_aspect_ratio", "0:1")]).unwrap().is_plain());
        assert_eq!(
            probe(&[("sample_aspect_ratio", "4:2")]).unwrap().sar,
            (2, 1)
        );
    }
}
