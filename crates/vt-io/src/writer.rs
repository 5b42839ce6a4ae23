//! Frame and image writers of every command, all through [`crate::output::Output`]: one ffmpeg
//! video writer (H.264 mp4, CRF 18 unless [`EncodeParams`] says otherwise; GIF with a
//! generated palette; lossless animated PNG), a PNG-frame folder, and
//! single images.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::{Arc, Mutex};

use image::RgbImage;

use crate::output::{self, Output, OutputKind};
use crate::{Error, Result};

/// The default x264 quality of the mp4s vt writes ([`EncodeParams::crf`]).
pub const MP4_CRF: u32 = 18;

/// How an mp4 is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EncodeParams {
    /// x264's constant rate factor, 0..=51: lower is closer to the frames and larger (18, x264's
    /// "visually lossless"). On `vt demo`'s 240-frame sweep, PSNR against the rendered frames
    /// and size: CRF 18 38.8 dB 165 KB, 12 40.0 dB 421 KB, 6 40.7 dB 1.4 MB, 0 41.0 dB 2.8 MB;
    /// the ceiling near 41 dB is the 4:2:0 chroma every player expects, not the rate.
    pub crf: u32,
}

impl Default for EncodeParams {
    fn default() -> Self {
        Self { crf: MP4_CRF }
    }
}

impl EncodeParams {
    /// Checks the range; the message names the value as `--crf`.
    pub fn check(&self) -> std::result::Result<(), String> {
        if self.crf > 51 {
            return Err(format!(
                "--crf {} must be in 0..=51 (x264's range)",
                self.crf
            ));
        }
        Ok(())
    }
}

/// An ffmpeg process encoding raw RGB frames into a temporary file that becomes the output on
/// [`VideoWriter::finish`]. Dropped unfinished, ffmpeg is killed and the temporary removed.
///
/// Frames go to ffmpeg through a thread of the writer's own with a queue of [`QUEUED`] frames, so
/// the caller renders the next frames while ffmpeg is still taking in one (a pipe holds 64 KiB,
/// a small part of a frame: written directly, every frame waited for ffmpeg to read it whole).
pub struct VideoWriter {
    output: Option<Output>,
    child: Arc<Mutex<Child>>,
    /// Frames to the feeding thread; None once closed.
    frames: Option<std::sync::mpsc::SyncSender<Vec<u8>>>,
    /// Buffers the feeding thread has written, for the next frames.
    spare: std::sync::mpsc::Receiver<Vec<u8>>,
    /// The feeding thread: its write error, if any.
    feeder: Option<std::thread::JoinHandle<std::io::Result<()>>>,
    stderr: Option<std::thread::JoinHandle<String>>,
    size: (u32, u32),
}

/// The video names vt writes: H.264 `mp4` (lossy, small, every player), `gif` (256 colours a
/// frame) and `apng` (animated PNG: lossless, large; browsers play it as an image). GIF and APNG
/// files repeat forever in players; an mp4 repeats where the player is told to loop.
pub const VIDEO_EXTENSIONS: [&str; 3] = ["mp4", "gif", "apng"];

/// Frames queued for ffmpeg beyond the one being written.
const QUEUED: usize = 2;

/// Writes each queued frame to ffmpeg's input and hands its buffer back; closes the input when
/// the queue closes, and stops at the first error.
fn feed(
    mut stdin: ChildStdin,
    frames: std::sync::mpsc::Receiver<Vec<u8>>,
    spare: std::sync::mpsc::SyncSender<Vec<u8>>,
) -> std::io::Result<()> {
    for frame in frames {
        stdin.write_all(&frame)?;
        let _ = spare.try_send(frame);
    }
    Ok(())
}

fn video_err(path: &Path, message: String) -> Error {
    Error::Video {
        path: path.to_path_buf(),
        message,
    }
}

/// The last non-empty line of ffmpeg's messages.
fn last_line(s: &str) -> String {
    s.lines()
        .map(str::trim)
        .rfind(|l| !l.is_empty())
        .unwrap_or("no message")
        .to_string()
}

impl VideoWriter {
    /// Starts encoding `w x h` frames at `fps` into `target` (`.mp4`, `.gif` or `.apng`: see
    /// [`VIDEO_EXTENSIONS`]), which is checked
    /// against `inputs` and existing files as every vt output is; mp4 at the default quality.
    pub fn create(target: &Path, inputs: &[&Path], w: u32, h: u32, fps: f64) -> Result<Self> {
        Self::create_with(target, inputs, w, h, fps, &EncodeParams::default())
    }

    /// [`VideoWriter::create`] with the mp4's encoding settings.
    pub fn create_with(
        target: &Path,
        inputs: &[&Path],
        w: u32,
        h: u32,
        fps: f64,
        enc: &EncodeParams,
    ) -> Result<Self> {
        enc.check().map_err(|m| video_err(target, m))?;
        let ext = ext_of(target).filter(|e| VIDEO_EXTENSIONS.contains(&e.as_str()));
        let Some(ext) = ext else {
            return Err(video_err(
                target,
                "a video must be named .mp4, .gif or .apng".into(),
            ));
        };
        if w == 0 || h == 0 || !(fps.is_finite() && fps > 0.0) {
            return Err(video_err(
                target,
                format!("cannot encode {w}x{h} at {fps} fps"),
            ));
        }
        let output = Output::file(target, OutputKind::Video, inputs)?;
        let mut cmd = Command::new("ffmpeg");
        cmd.args(["-hide_banner", "-v", "error", "-y", "-f", "rawvideo"])
            .args(["-pix_fmt", "rgb24", "-s", &format!("{w}x{h}")])
            .args(["-r", &fps.to_string(), "-i", "-"]);
        match ext.as_str() {
            // GIF and APNG repeat forever in players (GIF's muxer writes the loop by default).
            "gif" => {
                cmd.args([
                    "-filter_complex",
                    "[0:v]split[a][b];[a]palettegen[p];[b][p]paletteuse",
                    "-f",
                    "gif",
                ]);
            }
            "apng" => {
                cmd.args([
                    "-c:v", "apng", "-pix_fmt", "rgb24", "-plays", "0", "-f", "apng",
                ]);
            }
            _ => {
                cmd.args(["-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-c:v", "libx264"])
                    .args(["-pix_fmt", "yuv420p", "-crf", &enc.crf.to_string()])
                    .args(output.mp4_marker_args()?)
                    .args(["-movflags", "+faststart", "-f", "mp4"]);
            }
        }
        let mut child = cmd
            .arg(output.path())
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| {
                video_err(
                    target,
                    if e.kind() == std::io::ErrorKind::NotFound {
                        "writing video needs `ffmpeg` (Debian: apt-get install ffmpeg); or write PNG frames to a folder".into()
                    } else {
                        format!("cannot run ffmpeg: {e}")
                    },
                )
            })?;
        let stdin = child.stdin.take();
        let (frames, queue) = std::sync::mpsc::sync_channel(QUEUED);
        let (give_back, spare) = std::sync::mpsc::sync_channel(QUEUED + 1);
        let feeder = stdin.map(|stdin| {
            std::thread::Builder::new()
                .name("vt-ffmpeg-feed".into())
                .spawn(move || feed(stdin, queue, give_back))
        });
        let feeder = match feeder.transpose() {
            Ok(f) => f,
            Err(e) => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(video_err(
                    target,
                    format!("cannot start feeding ffmpeg: {e}"),
                ));
            }
        };
        let stderr = child.stderr.take().map(crate::video::drain);
        let child = Arc::new(Mutex::new(child));
        output::register_child(&child);
        Ok(Self {
            output: Some(output),
            child,
            frames: Some(frames),
            spare,
            feeder,
            stderr,
            size: (w, h),
        })
    }

    fn target(&self) -> PathBuf {
        self.output
            .as_ref()
            .map(|o| o.target().to_path_buf())
            .unwrap_or_default()
    }

    /// Closes the queue and waits for the feeding thread (its write error, if any).
    fn close_feed(&mut self) -> Option<std::io::Error> {
        drop(self.frames.take());
        self.feeder
            .take()
            .and_then(|t| t.join().unwrap_or(Ok(())).err())
    }

    /// Waits for ffmpeg (after the frames queued for it); its last message when it failed.
    fn wait(&mut self) -> Result<Option<String>> {
        if let Some(e) = self.close_feed() {
            // ffmpeg stopped taking frames: its own status says why, below; a write error
            // with a successful status is an error all the same.
            let status = self.child.lock().unwrap_or_else(|e| e.into_inner()).wait();
            if status.is_ok_and(|s| s.success()) {
                return Ok(Some(e.to_string()));
            }
        }
        let status = self
            .child
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .wait()
            .map_err(|e| video_err(&self.target(), format!("waiting for ffmpeg: {e}")))?;
        output::unregister_child(&self.child);
        let messages = self
            .stderr
            .take()
            .and_then(|t| t.join().ok())
            .unwrap_or_default();
        Ok((!status.success()).then(|| format!("{status}: {}", last_line(&messages))))
    }

    /// Sends one frame. When ffmpeg has stopped, the error carries ffmpeg's own message.
    pub fn write(&mut self, img: &RgbImage) -> Result<()> {
        if img.dimensions() != self.size {
            return Err(video_err(
                &self.target(),
                format!(
                    "frame is {}x{}, the video is {}x{}",
                    img.width(),
                    img.height(),
                    self.size.0,
                    self.size.1
                ),
            ));
        }
        let Some(frames) = self.frames.as_ref() else {
            return Err(video_err(&self.target(), "ffmpeg already finished".into()));
        };
        let mut buf = self.spare.try_recv().unwrap_or_default();
        buf.clear();
        buf.extend_from_slice(img.as_raw());
        if frames.send(buf).is_err() {
            // The feeding thread stopped: ffmpeg no longer reads.
            let why = self
                .wait()?
                .unwrap_or_else(|| "it stopped reading frames".into());
            return Err(video_err(
                &self.target(),
                format!("ffmpeg stopped encoding ({why})"),
            ));
        }
        Ok(())
    }

    /// Closes the stream, waits for ffmpeg, marks the file and moves it into place.
    pub fn finish(mut self) -> Result<PathBuf> {
        if let Some(why) = self.wait()? {
            return Err(video_err(&self.target(), format!("ffmpeg failed ({why})")));
        }
        let output = self.output.take().expect("finish runs once");
        output.commit()
    }
}

impl Drop for VideoWriter {
    fn drop(&mut self) {
        if self.output.is_some() {
            drop(self.frames.take());
            let mut c = self.child.lock().unwrap_or_else(|e| e.into_inner());
            let _ = c.kill();
            let _ = c.wait();
            drop(c);
            // ffmpeg is gone: a write in progress fails, and the thread ends.
            if let Some(t) = self.feeder.take() {
                let _ = t.join();
            }
            output::unregister_child(&self.child);
        }
        // `output` drops here and removes the temporary.
    }
}

fn ext_of(p: &Path) -> Option<String> {
    p.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
}

/// Whether `a` becomes `b` by one edit (a letter added, dropped, changed, or two neighbours
/// swapped), ASCII case ignored; both at least 3 letters long.
fn one_edit_apart(a: &str, b: &str) -> bool {
    let (a, b) = (a.to_ascii_lowercase(), b.to_ascii_lowercase());
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a == b || a.len() < 3 || b.len() < 3 || a.len().abs_diff(b.len()) > 1 {
        return false;
    }
    let pre = a.iter().zip(b).take_while(|(x, y)| x == y).count();
    let (ra, rb) = (&a[pre..], &b[pre..]);
    match (ra.len(), rb.len()) {
        (n, m) if n == m => {
            ra[1..] == rb[1..] || (n >= 2 && ra[0] == rb[1] && ra[1] == rb[0] && ra[2..] == rb[2..])
        }
        (n, m) if n > m => ra[1..] == *rb,
        _ => *ra == rb[1..],
    }
}

/// Where rendered frames go: a video through ffmpeg, or a folder of PNG frames.
pub enum FrameWriter {
    /// `.mp4`, `.gif` or `.apng`.
    Video(VideoWriter),
    /// A folder of `frame_NNNNN.png`.
    Folder {
        /// The folder being written.
        output: Output,
        /// Frames written.
        count: usize,
    },
}

impl FrameWriter {
    /// Chooses by the name: `.mp4`, `.gif`, `.apng`, or else a PNG folder, whatever dots its name has
    /// (`run.v2`, `frames.2024`); image and other video extensions are refused, and so are
    /// misspellings of them (one letter added, dropped, changed or swapped: `.mpg4`, `.gfi`),
    /// since a folder named like a file is surely a mistake.
    pub fn create(target: &Path, inputs: &[&Path], w: u32, h: u32, fps: f64) -> Result<Self> {
        Self::create_with(target, inputs, w, h, fps, &EncodeParams::default())
    }

    /// [`FrameWriter::create`] with the mp4's encoding settings (unused for GIF and folders).
    pub fn create_with(
        target: &Path,
        inputs: &[&Path],
        w: u32,
        h: u32,
        fps: f64,
        enc: &EncodeParams,
    ) -> Result<Self> {
        const REFUSED: [&str; 11] = [
            "png", "jpg", "jpeg", "avi", "mov", "mkv", "webm", "m4v", "mpg", "mpeg", "webp",
        ];
        let ext = ext_of(target).filter(|e| {
            VIDEO_EXTENSIONS.contains(&e.as_str())
                || REFUSED.contains(&e.as_str())
                || VIDEO_EXTENSIONS
                    .iter()
                    .chain(&REFUSED)
                    .any(|k| one_edit_apart(e, k))
        });
        match ext.as_deref() {
            None => Ok(FrameWriter::Folder {
                output: Output::dir(target, OutputKind::Frames, inputs)?,
                count: 0,
            }),
            Some(e) if VIDEO_EXTENSIONS.contains(&e) => Ok(FrameWriter::Video(
                VideoWriter::create_with(target, inputs, w, h, fps, enc)?,
            )),
            Some(other) => {
                let near = VIDEO_EXTENSIONS
                    .into_iter()
                    .find(|k| one_edit_apart(other, k))
                    .map(|k| format!(" (did you mean .{k}?)"))
                    .unwrap_or_default();
                Err(video_err(
                    target,
                    format!(
                        "unknown output extension '.{}'{near}: use .mp4, .gif, .apng, or a folder name (no extension) for PNG frames",
                        output::shorten(other)
                    ),
                ))
            }
        }
    }

    /// Writes the next frame.
    pub fn write(&mut self, img: &RgbImage) -> Result<()> {
        match self {
            FrameWriter::Video(v) => v.write(img),
            FrameWriter::Folder { output, count } => {
                crate::frames::write_png(
                    &output.path().join(format!("frame_{count:05}.png")),
                    img,
                )?;
                *count += 1;
                Ok(())
            }
        }
    }

    /// Finishes and moves the output into place.
    pub fn finish(self) -> Result<PathBuf> {
        match self {
            FrameWriter::Video(v) => v.finish(),
            FrameWriter::Folder { output, .. } => output.commit(),
        }
    }
}

/// Writes one image (`.png` or `.jpg`/`.jpeg`, by the name; RGB, or RGBA for a PNG) through a
/// temporary, marked as vt's.
pub fn write_image<P>(
    target: &Path,
    inputs: &[&Path],
    img: &image::ImageBuffer<P, Vec<P::Subpixel>>,
) -> Result<PathBuf>
where
    P: image::Pixel + image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
{
    let format = match ext_of(target).as_deref() {
        Some("png") => image::ImageFormat::Png,
        Some("jpg" | "jpeg") => image::ImageFormat::Jpeg,
        _ => {
            return Err(Error::Image {
                path: target.to_path_buf(),
                message: "use a .png or .jpg file name".into(),
            })
        }
    };
    let output = Output::file(target, OutputKind::Image, inputs)?;
    img.save_with_format(output.path(), format)
        .map_err(|e| Error::Image {
            path: target.to_path_buf(),
            message: e.to_string(),
        })?;
    output.commit()
}

#[cfg(test)]
mod tests {

    #[test]
    fn misspelt_video_names_are_refused_and_folder_names_with_dots_are_not() {
        for (a, b, want) in [
            ("mpg4", "mp4", true),
            ("mp5", "mp4", true),
            ("pm4", "mp4", true),
            ("gfi", "gif", true),
            ("gifs", "gif", true),
            ("MP4", "mp4", false),
            ("v2", "mp4", false),
            ("2024", "mp4", false),
            ("txt", "gif", false),
        ] {
            assert_eq!(one_edit_apart(a, b), want, "{a} vs {b}");
        }
        let dir = tempfile::tempdir().unwrap();
        let e = FrameWriter::create(&dir.path().join("trees.mpg4"), &[], 8, 8, 10.0)
            .err()
            .expect("refused")
            .to_string();
        assert!(e.contains("'.mpg4' (did you mean .mp4?)"), "{e}");
        assert!(!dir.path().join("trees.mpg4").exists());
        for ok in ["run.v2", "frames.2024"] {
            let w = FrameWriter::create(&dir.path().join(ok), &[], 8, 8, 10.0).unwrap();
            assert!(matches!(w, FrameWriter::Folder { .. }), "{ok}");
        }
    }
    use super::*;

    fn has_ffmpeg() -> bool {
        crate::video::ffmpeg_available()
    }

    #[test]
    fn videos_are_marked_replaceable_and_fail_cleanly() {
        if !has_ffmpeg() {
            eprintln!("skipped: no ffmpeg");
            return;
        }
        let dir = tempfile::tempdir().unwrap();
        let img = RgbImage::from_fn(33, 17, |x, y| image::Rgb([x as u8 * 7, y as u8 * 13, 99]));
        for name in ["a.mp4", "a.gif", "a.apng"] {
            let target = dir.path().join(name);
            for _ in 0..2 {
                let mut w = VideoWriter::create(&target, &[], 33, 17, 10.0).unwrap();
                for _ in 0..3 {
                    w.write(&img).unwrap();
                }
                w.finish().unwrap();
                assert!(
                    output::has_marker(&target, OutputKind::Video).unwrap(),
                    "{name}"
                );
            }
        }
        // vt's mp4 copied, or remuxed by ffmpeg (which keeps the metadata and so vt's
        // marker), to a new name is not replaceable; vt's own still is (above).
        let ours = dir.path().join("a.mp4");
        let copy = dir.path().join("copy.mp4");
        std::fs::copy(&ours, &copy).unwrap();
        let remux = dir.path().join("my_holiday.mp4");
        let st = std::process::Command::new("ffmpeg")
            .args(["-v", "error", "-i"])
            .arg(&ours)
            .args(["-c", "copy", "-map_metadata", "0"])
            .arg(&remux)
            .status()
            .unwrap();
        assert!(st.success());
        for p in [&copy, &remux] {
            let e = VideoWriter::create(p, &[], 33, 17, 10.0)
                .err()
                .expect("refused")
                .to_string();
            assert!(e.contains("not a vt video output written here"), "{e}");
        }
        // A user's file with the same name is refused and kept.
        let user = dir.path().join("mine.mp4");
        std::fs::write(&user, b"\0\0\0\x18ftypisom").unwrap();
        let e = VideoWriter::create(&user, &[], 33, 17, 10.0)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("not a vt video output"), "{e}");
        // An encoder that dies is reported as such, with its status, not as a broken pipe.
        let dead = dir.path().join("dead.mp4");
        let mut w = VideoWriter::create(&dead, &[], 33, 17, 10.0).unwrap();
        w.child.lock().unwrap().kill().unwrap();
        let e = (0..200)
            .find_map(|_| w.write(&img).err())
            .expect("writing to a dead encoder fails")
            .to_string();
        assert!(
            e.contains("ffmpeg stopped encoding (signal: 9") && !e.contains("Broken pipe"),
            "{e}"
        );
        drop(w);
        // A frame of the wrong size is refused with both sizes; nothing is left behind.
        let target = dir.path().join("b.mp4");
        let mut w = VideoWriter::create(&target, &[], 32, 16, 10.0).unwrap();
        let e = w.write(&img).unwrap_err().to_string();
        assert!(e.contains("33x17, the video is 32x16"), "{e}");
        drop(w);
        let names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
            .collect();
        assert!(
            !names.iter().any(|n| n.contains(".vt-tmp-") || n == "b.mp4"),
            "{names:?}"
        );
    }
}
