//! vt's documented limits on sizes that come from user input, and readers that check a file's
//! size before reading it whole. Every limit is checked before anything of that size is
//! allocated, and the message gives the number and the limit.
//!
//! | what | limit |
//! | --- | --- |
//! | a text file read whole (points file, `@FILE` path, par file) | [`MAX_TEXT_BYTES`] (64 MiB) |
//! | scene.json | [`MAX_SCENE_JSON_BYTES`] (256 MiB) |
//! | one moving-object store | [`MAX_OBJECT_STORE_BYTES`] (8 GiB) |
//! | an image file | [`MAX_IMAGE_FILE_BYTES`] (512 MiB) |
//! | an image's side / pixels (decoded) | [`MAX_IMAGE_SIDE`] (16384) / [`MAX_IMAGE_PIXELS`] (64 Mi) |
//! | views of a scene / frames of a view | [`MAX_VIEWS`] (1000) / [`MAX_FRAMES`] (1,000,000) |
//! | marked points per view | [`MAX_POINTS`] (10,000) |

use std::io::Read;
use std::path::Path;

use crate::{Error, Result};

/// Largest text file read whole (points, viewpoint lists, camera files).
pub const MAX_TEXT_BYTES: u64 = 64 << 20;
/// Largest scene.json.
pub const MAX_SCENE_JSON_BYTES: u64 = 256 << 20;
/// Largest moving-object store (version 1 is loaded whole for rendering; version 2 keeps its
/// index and reads each record when it is decoded).
pub const MAX_OBJECT_STORE_BYTES: u64 = 8 << 30;
/// Largest image file.
pub const MAX_IMAGE_FILE_BYTES: u64 = 512 << 20;
/// Longest image side, pixels.
pub const MAX_IMAGE_SIDE: u32 = 16384;
/// Most pixels in one image (8192 x 8192).
pub const MAX_IMAGE_PIXELS: u64 = 64 << 20;
/// Most views in a scene.
pub const MAX_VIEWS: usize = 1000;
/// Most frames in one view.
pub const MAX_FRAMES: usize = 1_000_000;
/// Most marked points per view.
pub const MAX_POINTS: usize = 10_000;

/// Human-readable bytes: `512 MiB`.
pub fn bytes(n: u64) -> String {
    const UNITS: [&str; 5] = ["bytes", "KiB", "MiB", "GiB", "TiB"];
    let mut v = n as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{n} bytes")
    } else if v.fract() == 0.0 {
        format!("{v:.0} {}", UNITS[u])
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

/// Parses a frame size `WxH` (e.g. `320x180`; `X` also separates), each side in
/// 8..=[`MAX_IMAGE_SIDE`]. The message quotes what was given.
pub fn parse_size(s: &str) -> std::result::Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("size '{s}' is not WxH (e.g. 320x180)"))?;
    let side = |v: &str, what: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("{what} '{v}' is not a whole number"))
    };
    let (w, h) = (side(w, "width")?, side(h, "height")?);
    if w < 8 || h < 8 || w > MAX_IMAGE_SIDE || h > MAX_IMAGE_SIDE {
        return Err(format!(
            "size {w}x{h} is out of range (8 to {MAX_IMAGE_SIDE} per side)"
        ));
    }
    Ok((w, h))
}

/// Fails unless the file at `path` is at most `limit` bytes; `what` names it in the message.
pub fn check_file_size(path: &Path, limit: u64, what: &str) -> Result<u64> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        return Err(Error::Limit {
            path: path.to_path_buf(),
            message: format!("is a folder, not a {what}"),
        });
    }
    if meta.len() > limit {
        return Err(Error::Limit {
            path: path.to_path_buf(),
            message: format!(
                "{} is {}, more than the {} vt reads",
                what,
                bytes(meta.len()),
                bytes(limit)
            ),
        });
    }
    Ok(meta.len())
}

/// Reads a whole file of at most `limit` bytes.
pub fn read_bytes(path: &Path, limit: u64, what: &str) -> Result<Vec<u8>> {
    let len = check_file_size(path, limit, what)?;
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut data = Vec::with_capacity(len as usize);
    // `take`: the file may grow after the check.
    f.take(limit + 1)
        .read_to_end(&mut data)
        .map_err(|e| Error::io(path, e))?;
    if data.len() as u64 > limit {
        return Err(Error::Limit {
            path: path.to_path_buf(),
            message: format!("{what} grew past the {} vt reads", bytes(limit)),
        });
    }
    Ok(data)
}

/// Reads a whole UTF-8 text file of at most `limit` bytes.
pub fn read_text(path: &Path, limit: u64, what: &str) -> Result<String> {
    let data = read_bytes(path, limit, what)?;
    String::from_utf8(data).map_err(|e| Error::Limit {
        path: path.to_path_buf(),
        message: format!(
            "{what} is not UTF-8 text (invalid byte at offset {})",
            e.utf8_error().valid_up_to()
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_are_checked_before_reading() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.txt");
        std::fs::write(&p, vec![b'1'; 2000]).unwrap();
        let e = read_text(&p, 1024, "points file").unwrap_err().to_string();
        assert!(
            e.contains("points file is 2.0 KiB, more than the 1 KiB vt reads"),
            "{e}"
        );
        assert_eq!(read_text(&p, 4096, "x").unwrap().len(), 2000);
        std::fs::write(&p, [0xFF, 0xFE, b'a']).unwrap();
        let e = read_text(&p, 4096, "points file").unwrap_err().to_string();
        assert!(e.contains("not UTF-8"), "{e}");
        assert_eq!(bytes(512 << 20), "512 MiB");
        assert_eq!(bytes(17), "17 bytes");
    }

    #[test]
    fn frame_sizes_parse_within_limits() {
        assert_eq!(parse_size("320x180"), Ok((320, 180)));
        assert_eq!(parse_size(" 64 X 48 "), Ok((64, 48)));
        assert_eq!(parse_size("16384x8"), Ok((16384, 8)));
        for (bad, says) in [
            ("320by180", "size '320by180' is not WxH"),
            ("4x4", "out of range (8 to 16384 per side)"),
            ("16385x8", "out of range"),
            ("99999999999x9", "width '99999999999' is not a whole number"),
            ("9x-1", "height '-1'"),
        ] {
            let e = parse_size(bad).unwrap_err();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }
}
