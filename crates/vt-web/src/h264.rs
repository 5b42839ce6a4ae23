//! One view's object frames as one H.264 stream for the browser's WebCodecs `VideoDecoder`:
//! every frame cropped to the union of the view's boxes (a video has one picture size), pixels
//! outside the masks from the background (static, so they cost next to nothing between frames),
//! main profile without B-frames (decode order is display order), BT.601 limited range
//! signalled in the stream, Annex B with an access unit delimiter before each frame so the
//! stream splits into per-frame chunks. Encoded by the `ffmpeg` program (libx264), which vt
//! already needs for video.

use std::io::{Read, Write};
use std::process::{Command, Stdio};

use crate::{Error, Result};

/// An encoded view: the access units in frame order, whether each is a key frame, and the codec
/// string (`avc1.PPCCLL` from the stream's SPS).
pub struct Stream {
    /// One access unit per frame (Annex B bytes).
    pub units: Vec<Vec<u8>>,
    /// Per unit: an IDR picture (decodable on its own).
    pub key: Vec<bool>,
    /// WebCodecs codec string.
    pub codec: String,
}

/// Encodes `n` frames of `w x h` RGB (`frame(i)` writes frame i into the buffer it is given)
/// at constant rate factor `crf`; `what` names the view in errors.
pub fn encode(
    w: u32,
    h: u32,
    crf: u8,
    n: usize,
    what: &str,
    frame: &mut dyn FnMut(usize, &mut Vec<u8>) -> Result<()>,
) -> Result<Stream> {
    let err = |message: String| Error::Encode {
        what: what.to_string(),
        message,
    };
    let mut child = Command::new("ffmpeg")
        .args(["-v", "error", "-nostdin", "-f", "rawvideo", "-pix_fmt", "rgb24"])
        .args(["-s", &format!("{w}x{h}"), "-r", "25", "-i", "-"])
        .args([
            "-vf",
            "pad=ceil(iw/2)*2:ceil(ih/2)*2,scale=out_color_matrix=bt601:out_range=tv",
            "-c:v",
            "libx264",
            "-profile:v",
            "main",
            "-bf",
            "0",
            "-pix_fmt",
            "yuv420p",
            "-crf",
            &crf.min(51).to_string(),
            "-x264-params",
            &format!("aud=1:keyint={g}:min-keyint={g}:scenecut=0", g = crate::H264_GROUP),
            "-colorspace",
            "smpte170m",
            "-color_primaries",
            "smpte170m",
            "-color_trc",
            "smpte170m",
            "-color_range",
            "tv",
            "-f",
            "h264",
            "-",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| {
            err(if e.kind() == std::io::ErrorKind::NotFound {
                "`ffmpeg` is not installed (Debian: apt-get install ffmpeg); --media jpeg needs none"
                    .into()
            } else {
                format!("cannot run ffmpeg: {e}")
            })
        })?;
    let mut stdout = child.stdout.take().expect("stdout was piped");
    let mut stderr = child.stderr.take().expect("stderr was piped");
    let out_thread = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = stdout.read_to_end(&mut v);
        v
    });
    let err_thread = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stderr.read_to_string(&mut s);
        s
    });
    let mut result = Ok(());
    {
        let mut stdin = child.stdin.take().expect("stdin was piped");
        let mut buf = Vec::new();
        for i in 0..n {
            buf.clear();
            if let Err(e) = frame(i, &mut buf) {
                result = Err(e);
                break;
            }
            if buf.len() != w as usize * h as usize * 3 {
                result = Err(err(format!("frame {i} has {} bytes", buf.len())));
                break;
            }
            if let Err(e) = stdin.write_all(&buf) {
                result = Err(err(format!("ffmpeg stopped accepting frames: {e}")));
                break;
            }
        }
    }
    if result.is_err() {
        let _ = child.kill();
    }
    let status = child
        .wait()
        .map_err(|e| err(format!("waiting for ffmpeg: {e}")))?;
    let bytes = out_thread.join().unwrap_or_default();
    let message = err_thread.join().unwrap_or_default();
    result?;
    if !status.success() {
        return Err(err(format!("ffmpeg failed: {}", message.trim())));
    }
    let units = split_access_units(&bytes);
    if units.len() != n {
        return Err(err(format!(
            "ffmpeg wrote {} frames, {n} were given",
            units.len()
        )));
    }
    let key = units.iter().map(|u| nal_types(u).any(|t| t == 5)).collect();
    let codec = units
        .first()
        .and_then(|u| sps_codec(u))
        .unwrap_or_else(|| "avc1.42E01E".into());
    Ok(Stream { units, key, codec })
}

/// Decodes an Annex B stream of `w x h` pictures (even sides) with ffmpeg into I420 and converts
/// it to RGB as the page's shader does ([`to_rgb`]), calling `f(i, rgb)` for each frame in order.
pub fn decode(
    stream: &[u8],
    w: u32,
    h: u32,
    what: &str,
    f: &mut dyn FnMut(usize, &[u8]) -> Result<()>,
) -> Result<usize> {
    let err = |message: String| Error::Encode {
        what: what.to_string(),
        message,
    };
    let mut child = Command::new("ffmpeg")
        .args(["-v", "error", "-nostdin", "-f", "h264", "-i", "-"])
        .args(["-f", "rawvideo", "-pix_fmt", "yuv420p", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| err(format!("cannot run ffmpeg: {e}")))?;
    let mut stdin = child.stdin.take().expect("stdin was piped");
    let input = stream.to_vec();
    let writer = std::thread::spawn(move || {
        let _ = stdin.write_all(&input);
    });
    let mut stdout = child.stdout.take().expect("stdout was piped");
    let (wu, hu) = (w as usize, h as usize);
    let mut frame = vec![0u8; wu * hu * 3 / 2];
    let mut rgb = vec![0u8; wu * hu * 3];
    let mut n = 0;
    let mut result = Ok(());
    while stdout.read_exact(&mut frame).is_ok() {
        to_rgb(&frame, wu, hu, &mut rgb);
        if let Err(e) = f(n, &rgb) {
            result = Err(e);
            break;
        }
        n += 1;
    }
    if result.is_err() {
        let _ = child.kill();
    }
    let _ = writer.join();
    let status = child
        .wait()
        .map_err(|e| err(format!("waiting for ffmpeg: {e}")))?;
    result?;
    if !status.success() {
        return Err(err("ffmpeg could not decode the encoded frames".into()));
    }
    Ok(n)
}

/// I420 (even sides) to RGB as `composite.frag` converts it: BT.601 limited range, each chroma
/// sample for its 2x2 block.
fn to_rgb(i420: &[u8], w: usize, h: usize, rgb: &mut [u8]) {
    let (y_plane, chroma) = i420.split_at(w * h);
    let (u_plane, v_plane) = chroma.split_at(w * h / 4);
    for y in 0..h {
        for x in 0..w {
            let c = (y / 2) * (w / 2) + x / 2;
            let l = (y_plane[y * w + x] as f32 - 16.0) * (255.0 / 219.0);
            let u = u_plane[c] as f32 - 128.0;
            let v = v_plane[c] as f32 - 128.0;
            let px = [
                l + 1.596027 * v,
                l - 0.391762 * u - 0.812968 * v,
                l + 2.017232 * u,
            ];
            for k in 0..3 {
                rgb[3 * (y * w + x) + k] = (px[k] + 0.5).clamp(0.0, 255.0) as u8;
            }
        }
    }
}

/// Start offsets of the NAL units of an Annex B stream (after their start codes), with the
/// start code's offset.
fn nal_starts(b: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i + 3 <= b.len() {
        if b[i] == 0 && b[i + 1] == 0 && b[i + 2] == 1 {
            let code = if i > 0 && b[i - 1] == 0 { i - 1 } else { i };
            out.push((code, i + 3));
            i += 3;
        } else {
            i += 1;
        }
    }
    out
}

/// NAL unit types of an Annex B chunk.
fn nal_types(b: &[u8]) -> impl Iterator<Item = u8> + '_ {
    nal_starts(b)
        .into_iter()
        .filter_map(|(_, s)| b.get(s).map(|h| h & 0x1f))
}

/// The stream cut before each access unit delimiter (NAL type 9).
fn split_access_units(b: &[u8]) -> Vec<Vec<u8>> {
    let cuts: Vec<usize> = nal_starts(b)
        .into_iter()
        .filter(|&(_, s)| b.get(s).is_some_and(|h| h & 0x1f == 9))
        .map(|(code, _)| code)
        .collect();
    cuts.iter()
        .enumerate()
        .map(|(k, &start)| b[start..cuts.get(k + 1).copied().unwrap_or(b.len())].to_vec())
        .collect()
}

/// `avc1.PPCCLL` from the first SPS (NAL type 7) in `b`.
fn sps_codec(b: &[u8]) -> Option<String> {
    let (_, s) = nal_starts(b)
        .into_iter()
        .find(|&(_, s)| b.get(s).is_some_and(|h| h & 0x1f == 7))?;
    let p = b.get(s + 1..s + 4)?;
    Some(format!("avc1.{:02X}{:02X}{:02X}", p[0], p[1], p[2]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn access_units_split_at_delimiters() {
        let stream = [
            0, 0, 0, 1, 9, 0xf0, 0, 0, 0, 1, 0x67, 0x42, 0xc0, 0x1e, 0, 0, 1, 0x65, 1, 2, 0, 0, 0,
            1, 9, 0xf0, 0, 0, 1, 0x41, 3,
        ];
        let units = split_access_units(&stream);
        assert_eq!(units.len(), 2);
        assert_eq!(units[1], vec![0, 0, 0, 1, 9, 0xf0, 0, 0, 1, 0x41, 3]);
        assert!(nal_types(&units[0]).any(|t| t == 5));
        assert!(!nal_types(&units[1]).any(|t| t == 5));
        assert_eq!(sps_codec(&units[0]).as_deref(), Some("avc1.42C01E"));
    }
}
