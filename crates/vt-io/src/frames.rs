//! Frame sources for views: a video file decoded by `ffmpeg`, or a folder of PNG/JPG frames.
//!
//! Videos are decoded with `-fps_mode passthrough`, so variable-frame-rate files give their real
//! frames (OpenCV's `tree.avi`: 68, not the 444 its header implies), and with `-xerror`, so a
//! truncated or corrupt file is an error rather than a silently shorter video.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use image::RgbImage;
use rayon::prelude::*;
use vt_core::analysis::{FrameRef, FrameSource};
use vt_core::yuv::{Yuv420Image, YuvMatrix, YuvRange};

use crate::{Error, Result};

/// Video file extensions vt decodes through ffmpeg.
pub const VIDEO_EXTENSIONS: [&str; 6] = ["mp4", "avi", "mov", "mkv", "webm", "m4v"];
/// Frame image extensions in folders.
pub const FRAME_EXTENSIONS: [&str; 6] = ["png", "jpg", "jpeg", "bmp", "tif", "tiff"];

fn has_ext(path: &Path, exts: &[&str]) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| exts.iter().any(|x| x.eq_ignore_ascii_case(e)))
}

/// A view's frames, from either kind of input.
pub enum ViewSource {
    /// A video file.
    Video(VideoSource),
    /// A folder of frames.
    Folder(FolderSource),
}

impl ViewSource {
    /// Opens a view: a folder of frames or a video file, decided by what the path is.
    pub fn open(path: &Path) -> Result<Self> {
        Ok(Self::open_probing(path, false)?.0)
    }

    /// [`ViewSource::open`], and a video's real frame rate from the same probe: one over the
    /// median interval between its frames' timestamps ([`crate::video::rate_from_timestamps`],
    /// so variable-frame-rate files such as OpenCV's `tree.avi` give the rate their frames
    /// really come at); None for a folder, or without timestamps. The probe reads the whole
    /// file's packets.
    pub fn open_timed(path: &Path) -> Result<(Self, Option<f64>)> {
        Self::open_probing(path, true)
    }

    fn open_probing(path: &Path, timed: bool) -> Result<(Self, Option<f64>)> {
        if !path.exists() {
            return Err(Error::View {
                path: path.to_path_buf(),
                message: "no such file or directory".into(),
            });
        }
        if path.is_dir() {
            return Ok((ViewSource::Folder(FolderSource::open(path)?), None));
        }
        if has_ext(path, &VIDEO_EXTENSIONS) {
            let (video, rate) = VideoSource::probe(path, timed)?;
            return Ok((ViewSource::Video(video), rate));
        }
        Err(Error::View {
            path: path.to_path_buf(),
            message: format!(
                "not a view: expected a video ({}) or a folder of frames ({})",
                VIDEO_EXTENSIONS.join(", "),
                FRAME_EXTENSIONS.join(", ")
            ),
        })
    }

    /// What decoding a video does beyond reading its coded frames (turning a portrait clip,
    /// square pixels, deinterlacing), in words; empty for a folder or a plain video.
    pub fn notes(&self) -> Vec<String> {
        match self {
            ViewSource::Video(v) => v.notes(),
            ViewSource::Folder(_) => Vec::new(),
        }
    }

    /// Frame size.
    pub fn size(&self) -> (u32, u32) {
        match self {
            ViewSource::Video(v) => (v.width, v.height),
            ViewSource::Folder(f) => f.size,
        }
    }

    /// The source as vt-core's trait object.
    pub fn as_source(&mut self) -> &mut dyn FrameSource {
        match self {
            ViewSource::Video(v) => v,
            ViewSource::Folder(f) => f,
        }
    }

    /// Decodes every frame into memory, for short inputs used whole (`vt synth real`'s
    /// source, tests); analysis streams views instead.
    pub fn read_all(&mut self) -> Result<Vec<RgbImage>> {
        let mut frames = Vec::new();
        self.as_source().for_each_frame(&mut |_, f| {
            frames.push(f.clone());
            Ok(())
        })?;
        Ok(frames)
    }
}

/// A video decoded by the `ffmpeg` program into raw RGB frames through a pipe.
pub struct VideoSource {
    path: PathBuf,
    name: String,
    width: u32,
    height: u32,
    /// The 4:2:0 form the decoder gives, when the stream is 4:2:0 (then frames are decoded as
    /// such and converted by [`vt_core::yuv`]); None: ffmpeg converts to RGB.
    yuv: Option<(YuvMatrix, YuvRange)>,
    /// How a player shows the stream (rotation, pixel aspect, interlacing), and so what the
    /// frames are decoded into; `width` and `height` are the shown size.
    display: crate::display::Display,
    /// The stream's coded frame size.
    coded: (u32, u32),
}

fn missing_tool(tool: &str, path: &Path, e: std::io::Error) -> Error {
    Error::Video {
        path: path.to_path_buf(),
        message: if e.kind() == std::io::ErrorKind::NotFound {
            format!(
                "cannot decode videos: `{tool}` is not installed (Debian: apt-get install ffmpeg)"
            )
        } else {
            format!("cannot run {tool}: {e}")
        },
    }
}

fn last_line(s: &str) -> String {
    s.lines()
        .map(str::trim)
        .rfind(|l| !l.is_empty())
        .unwrap_or("unknown error")
        .to_string()
}

impl VideoSource {
    /// Probes the video's size and pixel format with `ffprobe`.
    pub fn open(path: &Path) -> Result<Self> {
        Ok(Self::probe(path, false)?.0)
    }

    /// [`VideoSource::open`], and with `timed` the real frame rate from the same `ffprobe`
    /// run (its packets' timestamps: the whole file is read).
    fn probe(path: &Path, timed: bool) -> Result<(Self, Option<f64>)> {
        let mut entries = format!(
            "stream=width,height,pix_fmt,color_space,color_range:{}",
            crate::display::PROBE_ENTRIES
        );
        if timed {
            entries.push_str(":packet=pts_time");
        }
        let out = Command::new("ffprobe")
            .args([
                "-v",
                "error",
                "-select_streams",
                "v:0",
                "-show_entries",
                &entries,
                "-of",
                "default=noprint_wrappers=1",
            ])
            .arg(path)
            .stdin(Stdio::null())
            .output()
            .map_err(|e| missing_tool("ffprobe", path, e))?;
        let stdout = String::from_utf8_lossy(&out.stdout);
        let field = |key: &str| {
            stdout
                .lines()
                .find_map(|l| l.trim().strip_prefix(key)?.strip_prefix('='))
                .map(str::trim)
        };
        let dim = |key: &str| field(key).and_then(|v| v.parse::<u32>().ok());
        let dims = match (dim("width"), dim("height")) {
            (Some(w), Some(h)) if out.status.success() && w > 0 && h > 0 => (w, h),
            _ => {
                let err = String::from_utf8_lossy(&out.stderr);
                let why = if out.status.success() {
                    "no video stream".to_string()
                } else {
                    last_line(&err)
                };
                return Err(Error::Video {
                    path: path.to_path_buf(),
                    message: format!("not a readable video ({why})"),
                });
            }
        };
        check_image_size(path, dims)?;
        let display = crate::display::Display::from_probe(path, field)?;
        let coded = dims;
        let dims = display.shown_size(coded);
        check_image_size(path, dims)?;
        // The frames' own size, as the decode will hand them out, against what the header
        // says: a mismatch is refused rather than read as rows of another width.
        let decoded = crate::display::first_frame_size(path, display.filters().as_deref())?;
        if decoded != dims {
            return Err(Error::Video {
                path: path.to_path_buf(),
                message: format!(
                    "its frames decode as {}x{}, not the {}x{} its stream header gives \
                     ({}x{} coded{}); not read",
                    decoded.0,
                    decoded.1,
                    dims.0,
                    dims.1,
                    coded.0,
                    coded.1,
                    match display.describe(coded).first() {
                        Some(d) => format!(", {d}"),
                        None => String::new(),
                    }
                ),
            });
        }
        let even = dims.0 % 2 == 0 && dims.1 % 2 == 0;
        let yuv = match field("pix_fmt") {
            Some(fmt @ ("yuv420p" | "yuvj420p")) if even => {
                let full = fmt == "yuvj420p" || matches!(field("color_range"), Some("pc" | "jpeg"));
                let range = if full {
                    YuvRange::Full
                } else {
                    YuvRange::Limited
                };
                let matrix = match field("color_space") {
                    Some("bt709") => YuvMatrix::Bt709,
                    _ => YuvMatrix::Bt601,
                };
                Some((matrix, range))
            }
            _ => None,
        };
        let rate = timed
            .then(|| {
                let mut ts: Vec<f64> = stdout
                    .lines()
                    .filter_map(|l| l.trim().strip_prefix("pts_time=")?.parse().ok())
                    .filter(|t: &f64| t.is_finite())
                    .collect();
                ts.sort_by(f64::total_cmp);
                crate::video::rate_from_timestamps(&ts)
            })
            .flatten();
        Ok((
            Self {
                path: path.to_path_buf(),
                name: path.display().to_string(),
                width: dims.0,
                height: dims.1,
                yuv,
                display,
                coded,
            },
            rate,
        ))
    }

    /// Frame size: what a player shows (turned, square pixels).
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// How a player shows the stream, which the frames are decoded into.
    pub fn display(&self) -> crate::display::Display {
        self.display
    }

    /// What decoding does beyond reading the coded frames, in words (empty when nothing).
    pub fn notes(&self) -> Vec<String> {
        self.display.describe(self.coded)
    }
}

impl VideoSource {
    /// The 4:2:0 form frames are decoded in (None: RGB from ffmpeg).
    pub fn yuv_format(&self) -> Option<(YuvMatrix, YuvRange)> {
        self.yuv
    }

    fn src_err(&self, message: String) -> vt_core::Error {
        vt_core::Error::Source {
            view: self.name.clone(),
            message,
        }
    }

    /// Runs ffmpeg to decode every frame (or the first `end`) as raw `pix_fmt` of
    /// `frame_bytes` bytes, calling `on_frame(index, bytes)` for each; returns the frame count.
    fn decode(
        &self,
        pix_fmt: &str,
        frame_bytes: usize,
        end: Option<usize>,
        on_frame: &mut dyn FnMut(usize, &mut Vec<u8>) -> vt_core::Result<()>,
    ) -> vt_core::Result<usize> {
        if end == Some(0) {
            return Ok(0);
        }
        let mut child = Command::new("ffmpeg")
            .args(["-v", "error", "-xerror", "-nostdin", "-i"])
            .arg(&self.path)
            .args(["-map", "0:v:0"])
            .args(
                self.display
                    .filters()
                    .map(|f| vec!["-vf".to_string(), f])
                    .unwrap_or_default(),
            )
            .args(
                end.map(|n| vec!["-frames:v".to_string(), n.to_string()])
                    .unwrap_or_default(),
            )
            .args([
                "-fps_mode",
                "passthrough",
                "-f",
                "rawvideo",
                "-pix_fmt",
                pix_fmt,
                "-",
            ])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| self.src_err(missing_tool("ffmpeg", &self.path, e).to_string()))?;
        let err_thread = crate::video::drain(child.stderr.take().expect("stderr was piped"));
        let mut stdout = child.stdout.take().expect("stdout was piped");
        let mut buf = vec![0u8; frame_bytes];
        let mut n = 0usize;
        let result: vt_core::Result<()> = loop {
            let mut filled = 0;
            while filled < frame_bytes {
                match stdout.read(&mut buf[filled..]) {
                    Ok(0) => break,
                    Ok(k) => filled += k,
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(e) => return Err(self.src_err(format!("reading decoded frames: {e}"))),
                }
            }
            if filled == 0 {
                break Ok(());
            }
            if filled < frame_bytes {
                break Err(self.src_err(format!(
                    "truncated: frame {n} has {filled} of {frame_bytes} bytes"
                )));
            }
            if let Err(e) = on_frame(n, &mut buf) {
                break Err(e);
            }
            n += 1;
        };
        drop(stdout);
        if result.is_err() {
            let _ = child.kill();
        }
        let status = child
            .wait()
            .map_err(|e| self.src_err(format!("waiting for ffmpeg: {e}")))?;
        let err = err_thread.join().unwrap_or_default();
        result?;
        if !status.success() {
            return Err(self.src_err(format!(
                "unreadable or truncated video after {n} frames (ffmpeg: {})",
                last_line(&err)
            )));
        }
        if n == 0 {
            return Err(self.src_err("the video has no frames".into()));
        }
        Ok(n)
    }

    /// Decodes 4:2:0 frames, handing each out as a [`Yuv420Image`].
    fn decode_yuv(
        &self,
        (matrix, range): (YuvMatrix, YuvRange),
        end: Option<usize>,
        f: &mut dyn FnMut(usize, &Yuv420Image) -> vt_core::Result<()>,
    ) -> vt_core::Result<usize> {
        let (w, h) = (self.width, self.height);
        self.decode(
            "yuv420p",
            Yuv420Image::byte_len(w, h),
            end,
            &mut |i, buf| {
                let img = Yuv420Image::from_raw(w, h, matrix, range, std::mem::take(buf))?;
                let r = f(i, &img);
                *buf = img.into_raw();
                r
            },
        )
    }

    /// Decodes RGB frames (converted by ffmpeg).
    fn decode_rgb(
        &self,
        end: Option<usize>,
        f: &mut dyn FnMut(usize, &RgbImage) -> vt_core::Result<()>,
    ) -> vt_core::Result<usize> {
        let (w, h) = (self.width, self.height);
        self.decode("rgb24", w as usize * h as usize * 3, end, &mut |i, buf| {
            let img = RgbImage::from_raw(w, h, std::mem::take(buf)).expect("buffer is w*h*3");
            let r = f(i, &img);
            *buf = img.into_raw();
            r
        })
    }
}

impl FrameSource for VideoSource {
    fn name(&self) -> &str {
        &self.name
    }

    fn for_each_frame(
        &mut self,
        f: &mut dyn FnMut(usize, &RgbImage) -> vt_core::Result<()>,
    ) -> vt_core::Result<usize> {
        match self.yuv {
            Some(form) => {
                let mut rgb = RgbImage::new(self.width, self.height);
                self.decode_yuv(form, None, &mut |i, yuv| {
                    yuv.to_rgb_into(&mut rgb);
                    f(i, &rgb)
                })
            }
            None => self.decode_rgb(None, f),
        }
    }

    fn for_each_native(
        &mut self,
        f: &mut dyn FnMut(usize, FrameRef<'_>) -> vt_core::Result<()>,
    ) -> vt_core::Result<usize> {
        self.native(None, f)
    }

    fn for_each_native_to(
        &mut self,
        end: usize,
        f: &mut dyn FnMut(usize, FrameRef<'_>) -> vt_core::Result<()>,
    ) -> vt_core::Result<usize> {
        self.native(Some(end), f)
    }
}

impl VideoSource {
    /// The frames in their decoded form: every one, or the first `end`.
    fn native(
        &self,
        end: Option<usize>,
        f: &mut dyn FnMut(usize, FrameRef<'_>) -> vt_core::Result<()>,
    ) -> vt_core::Result<usize> {
        match self.yuv {
            Some(form) => self.decode_yuv(form, end, &mut |i, yuv| f(i, FrameRef::Yuv420(yuv))),
            None => self.decode_rgb(end, &mut |i, rgb| f(i, FrameRef::Rgb(rgb))),
        }
    }
}

/// A folder of frames (PNG or JPG), in file-name order.
pub struct FolderSource {
    name: String,
    files: Vec<PathBuf>,
    size: (u32, u32),
}

impl FolderSource {
    /// Lists the folder and reads the first frame's size.
    pub fn open(dir: &Path) -> Result<Self> {
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|e| Error::io(dir, e))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_file() && has_ext(p, &FRAME_EXTENSIONS))
            .collect();
        files.sort();
        let first = files.first().ok_or_else(|| Error::View {
            path: dir.to_path_buf(),
            message: format!("folder has no frames ({})", FRAME_EXTENSIONS.join(", ")),
        })?;
        let size = image::image_dimensions(first).map_err(|e| Error::Image {
            path: first.clone(),
            message: e.to_string(),
        })?;
        check_image_size(first, size)?;
        if files.len() > crate::limits::MAX_FRAMES {
            return Err(Error::Limit {
                path: dir.to_path_buf(),
                message: format!(
                    "{} frames, more than the {} vt reads per view",
                    files.len(),
                    crate::limits::MAX_FRAMES
                ),
            });
        }
        Ok(Self {
            name: dir.display().to_string(),
            files,
            size,
        })
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.files.len()
    }

    /// Never true for an opened folder.
    pub fn is_empty(&self) -> bool {
        self.files.is_empty()
    }
}

/// Refuses image sizes beyond [`crate::limits::MAX_IMAGE_SIDE`] per side or
/// [`crate::limits::MAX_IMAGE_PIXELS`] in all.
pub fn check_image_size(path: &Path, (w, h): (u32, u32)) -> Result<()> {
    use crate::limits::{MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE};
    if w == 0
        || h == 0
        || w > MAX_IMAGE_SIDE
        || h > MAX_IMAGE_SIDE
        || w as u64 * h as u64 > MAX_IMAGE_PIXELS
    {
        return Err(Error::Limit {
            path: path.to_path_buf(),
            message: format!(
                "image is {w}x{h}; vt reads 1 to {MAX_IMAGE_SIDE} pixels per side and at most {MAX_IMAGE_PIXELS} pixels"
            ),
        });
    }
    Ok(())
}

/// The image front door: decodes PNG, JPEG, BMP or TIFF bytes as RGB (8 bits per channel;
/// deeper TIFFs are scaled down) with the size limits of
/// [`crate::limits`] checked from the header, before the pixels are allocated. `path` names the
/// file in errors.
pub fn decode_rgb(bytes: &[u8], path: &Path) -> Result<RgbImage> {
    let bad = |e: image::ImageError| Error::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    if reader.format().is_none() {
        return Err(Error::Image {
            path: path.to_path_buf(),
            message: "not a PNG, JPEG, BMP or TIFF image".into(),
        });
    }
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(crate::limits::MAX_IMAGE_SIDE);
    limits.max_image_height = Some(crate::limits::MAX_IMAGE_SIDE);
    limits.max_alloc = Some(crate::limits::MAX_IMAGE_PIXELS * 4 + (64 << 20));
    reader.limits(limits);
    let decoder = reader.into_decoder().map_err(bad)?;
    let size = image::ImageDecoder::dimensions(&decoder);
    check_image_size(path, size)?;
    let img = image::DynamicImage::from_decoder(decoder).map_err(bad)?;
    Ok(img.to_rgb8())
}

/// Reads an image file as RGB through [`decode_rgb`] (file size at most
/// [`crate::limits::MAX_IMAGE_FILE_BYTES`]), naming the file in errors.
pub fn read_rgb(path: &Path) -> Result<RgbImage> {
    let bytes = crate::limits::read_bytes(path, crate::limits::MAX_IMAGE_FILE_BYTES, "image file")?;
    decode_rgb(&bytes, path)
}

impl FrameSource for FolderSource {
    fn name(&self) -> &str {
        &self.name
    }

    fn for_each_frame(
        &mut self,
        f: &mut dyn FnMut(usize, &RgbImage) -> vt_core::Result<()>,
    ) -> vt_core::Result<usize> {
        // Decode a chunk of frames in parallel, hand them over in order.
        let chunk = 2 * rayon::current_num_threads().max(1);
        let mut n = 0;
        for files in self.files.chunks(chunk) {
            let frames: Vec<Result<RgbImage>> = files.par_iter().map(|p| read_rgb(p)).collect();
            for (fr, file) in frames.into_iter().zip(files) {
                let fr = fr.map_err(|e| vt_core::Error::external(self.name.clone(), e))?;
                if fr.dimensions() != self.size {
                    return Err(vt_core::Error::Source {
                        view: self.name.clone(),
                        message: format!(
                            "{} is {}x{}, but the first frame is {}x{}",
                            file.display(),
                            fr.width(),
                            fr.height(),
                            self.size.0,
                            self.size.1
                        ),
                    });
                }
                f(n, &fr)?;
                n += 1;
            }
        }
        Ok(n)
    }
}

/// The frame size shared by every view (`sources[p]` opened from `paths[p]`), or
/// [`Error::ViewSizes`] naming the first view of another size.
pub fn common_size(paths: &[PathBuf], sources: &[ViewSource]) -> Result<(u32, u32)> {
    let first_size = sources.first().map_or((0, 0), ViewSource::size);
    match sources.iter().position(|s| s.size() != first_size) {
        None => Ok(first_size),
        Some(view) => Err(Error::ViewSizes {
            first: paths[0].clone(),
            first_size,
            view,
            path: paths[view].clone(),
            size: sources[view].size(),
        }),
    }
}

/// Writes an RGB image as PNG with fast compression (frames are noisy; strong compression buys
/// little and costs much), naming the file in errors.
pub fn write_png(path: &Path, img: &RgbImage) -> Result<()> {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    use image::ImageEncoder;
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let w = std::io::BufWriter::new(file);
    PngEncoder::new_with_quality(w, CompressionType::Fast, FilterType::Adaptive)
        .write_image(
            img.as_raw(),
            img.width(),
            img.height(),
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| Error::Image {
            path: path.to_path_buf(),
            message: e.to_string(),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first frames of a video, as a read that stops after them gives them, are the full
    /// read's frames; a read past the clip's end gives the whole clip.
    #[test]
    fn a_read_that_stops_early_gives_the_first_frames() {
        let tree = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/tree.avi");
        let mut src = VideoSource::open(&tree).expect("tree.avi opens");
        let mut all: Vec<Vec<u8>> = Vec::new();
        let n = src
            .for_each_native(&mut |_, f| {
                all.push(f.rgb(&mut RgbImage::new(0, 0)).as_raw().clone());
                Ok(())
            })
            .expect("a full read");
        assert_eq!(n, 68);
        for end in [1, 10, 68, 1000] {
            let mut first: Vec<Vec<u8>> = Vec::new();
            let got = src
                .for_each_native_to(end, &mut |i, f| {
                    assert!(i < end, "frame {i} past {end}");
                    first.push(f.rgb(&mut RgbImage::new(0, 0)).as_raw().clone());
                    Ok(())
                })
                .expect("a read to a frame");
            assert_eq!(got, end.min(68), "end {end}");
            assert!(first == all[..got], "end {end}: other frames");
        }
    }
}
