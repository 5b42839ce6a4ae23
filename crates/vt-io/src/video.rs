//! Video timing and encoding: a video's real frame rate from its frames' timestamps (the median
//! interval, so variable-frame-rate files such as OpenCV's `tree.avi` give the rate their frames
//! really come at; the timestamps come from the probe of
//! [`crate::frames::ViewSource::open_timed`]) and H.264 encoding of frames made in memory through
//! the `ffmpeg` program.

use std::io::{Read, Write};
use std::path::Path;
use std::process::{Command, Stdio};

use image::RgbImage;

use crate::{Error, Result};

fn video_err(path: &Path, message: String) -> Error {
    Error::Video {
        path: path.to_path_buf(),
        message,
    }
}

fn spawn_err(tool: &str, path: &Path, e: std::io::Error) -> Error {
    video_err(
        path,
        if e.kind() == std::io::ErrorKind::NotFound {
            format!("`{tool}` is not installed (Debian: apt-get install ffmpeg)")
        } else {
            format!("cannot run {tool}: {e}")
        },
    )
}

/// Reads a child's stderr to its end on a thread of its own (so a chatty ffmpeg never blocks on
/// a full pipe); the thread returns what it said.
pub(crate) fn drain(mut stderr: impl Read + Send + 'static) -> std::thread::JoinHandle<String> {
    std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stderr.read_to_string(&mut s);
        s
    })
}

/// Whether the `ffmpeg` program runs (`ffmpeg -version` succeeds).
pub fn ffmpeg_available() -> bool {
    Command::new("ffmpeg")
        .arg("-version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// The frame rate of a scene's views: the median of the videos' own rates (from
/// [`crate::frames::ViewSource::open_timed`]); None when none has one (frame folders).
pub fn views_frame_rate(rates: impl IntoIterator<Item = Option<f64>>) -> Option<f64> {
    let mut rates: Vec<f64> = rates.into_iter().flatten().collect();
    if rates.is_empty() {
        return None;
    }
    rates.sort_by(f64::total_cmp);
    Some(rates[(rates.len() - 1) / 2])
}

/// One over the median positive interval of sorted timestamps (seconds).
pub fn rate_from_timestamps(sorted: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = sorted
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|&d| d > 1e-6)
        .collect();
    if d.is_empty() {
        return None;
    }
    let mid = d.len() / 2;
    let (_, med, _) = d.select_nth_unstable_by(mid, f64::total_cmp);
    let fps = 1.0 / *med;
    (fps.is_finite() && fps > 0.0).then_some(fps)
}

/// Encodes `n` frames (`frame(i)` for i in 0..n, all `w x h`) to H.264 in an MP4 at `path`
/// (`crf`: 0 lossless .. 51; yuv420p, even sizes padded), at `fps` frames per second.
pub fn encode_h264(
    path: &Path,
    w: u32,
    h: u32,
    fps: f64,
    crf: u8,
    n: usize,
    frame: &mut dyn FnMut(usize) -> Result<RgbImage>,
) -> Result<()> {
    if !(fps.is_finite() && fps > 0.0) {
        return Err(video_err(path, format!("frame rate {fps} is not positive")));
    }
    let mut child = Command::new("ffmpeg")
        .args([
            "-v", "error", "-y", "-nostdin", "-f", "rawvideo", "-pix_fmt", "rgb24",
        ])
        .args([
            "-s",
            &format!("{w}x{h}"),
            "-r",
            &format!("{fps}"),
            "-i",
            "-",
        ])
        .args([
            "-vf",
            "pad=ceil(iw/2)*2:ceil(ih/2)*2",
            "-c:v",
            "libx264",
            "-pix_fmt",
            "yuv420p",
            "-crf",
            &crf.min(51).to_string(),
            "-f",
            "mp4",
        ])
        .arg(path)
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| spawn_err("ffmpeg", path, e))?;
    let err_thread = drain(child.stderr.take().expect("stderr was piped"));
    let mut result = Ok(());
    {
        let mut stdin = child.stdin.take().expect("stdin was piped");
        for i in 0..n {
            let img = match frame(i) {
                Ok(img) => img,
                Err(e) => {
                    result = Err(e);
                    break;
                }
            };
            if img.dimensions() != (w, h) {
                result = Err(video_err(
                    path,
                    format!(
                        "frame {i} is {}x{}, the video is {w}x{h}",
                        img.width(),
                        img.height()
                    ),
                ));
                break;
            }
            if let Err(e) = stdin.write_all(img.as_raw()) {
                result = Err(video_err(
                    path,
                    format!("ffmpeg stopped accepting frames: {e}"),
                ));
                break;
            }
        }
    }
    if result.is_err() {
        let _ = child.kill();
    }
    let status = child
        .wait()
        .map_err(|e| video_err(path, format!("waiting for ffmpeg: {e}")))?;
    let err = err_thread.join().unwrap_or_default();
    result?;
    if !status.success() {
        return Err(video_err(
            path,
            format!(
                "ffmpeg failed to encode: {}",
                err.lines().last().unwrap_or("unknown error").trim()
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_interval_ignores_gaps_and_duplicates() {
        // tree.avi-like: mostly 0.4 s apart, a few 0.67 s gaps and a duplicate stamp.
        let ts = [0.0, 0.4, 0.8, 0.8, 1.47, 1.87, 2.27, 2.94, 3.34];
        let fps = rate_from_timestamps(&ts).unwrap();
        assert!((fps - 2.5).abs() < 1e-9, "{fps}");
        assert_eq!(rate_from_timestamps(&[1.0]), None);
    }
}
