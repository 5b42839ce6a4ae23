//! vt's marker in the files and folders it writes: what kind of output, and which very file
//! (device, inode and path), embedded in the file's own metadata.

use super::*;

/// What a marker records about the output it is in, so that only the very file or folder vt
/// wrote there matches it: the device and inode of the written file (kept by the rename into
/// place; new for any copy, and for another tool's rewrite to a new file) and a hash of the
/// final path (another for a copy or a move to another name). `file`: the file or folder to
/// take the inode of (the temporary while writing, the target when checking); `target`: where
/// it is (to be).
pub(super) fn identity(file: &Path, target: &Path) -> Result<String> {
    let meta = std::fs::metadata(file).map_err(|e| Error::io(file, e))?;
    #[cfg(unix)]
    let (dev, ino) = {
        use std::os::unix::fs::MetadataExt;
        (meta.dev(), meta.ino())
    };
    #[cfg(not(unix))]
    let (dev, ino) = {
        let _ = meta;
        (0u64, 0u64)
    };
    let place = canonical_target(target).unwrap_or_else(|| target.to_path_buf());
    // FNV-1a over the path's bytes.
    let hash = place
        .to_string_lossy()
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
        });
    Ok(format!("{dev:x}-{ino:x}-{hash:016x}"))
}

/// Adds vt's marker to a finished file, in a way its format allows: a first line `# MARKER` in
/// a points file (text), a PNG `tEXt` chunk after
/// `IHDR`, a JPEG `COM` segment after `SOI`, a GIF comment extension before the trailer. MP4 files
/// get theirs from the encoder (`-metadata comment=...`, see [`mp4_marker_args`]) and are only
/// checked here. The marker records the identity of `path` as the file that will be at `target`
/// ([`identity`]); the marking rewrites `path` in place (same inode).
pub fn embed_marker(path: &Path, kind: OutputKind, target: &Path) -> Result<()> {
    let mut head = [0u8; 8];
    let mut f = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(path)
        .map_err(|e| Error::io(path, e))?;
    let n = f.read(&mut head).map_err(|e| Error::io(path, e))?;
    let marker = kind.marker(&identity(path, target)?);
    let io = |e| Error::io(path, e);
    if kind == OutputKind::Points {
        let mut data = format!("# {marker}\n").into_bytes();
        f.seek(SeekFrom::Start(0)).map_err(io)?;
        f.read_to_end(&mut data).map_err(io)?;
        std::fs::write(path, data).map_err(io)
    } else if n == 8 && head == *b"\x89PNG\r\n\x1a\n" {
        let mut data = Vec::new();
        f.seek(SeekFrom::Start(0)).map_err(io)?;
        f.read_to_end(&mut data).map_err(io)?;
        let ihdr_end = 8 + 25;
        if data.len() < ihdr_end || &data[12..16] != b"IHDR" {
            return Err(out_err(path, "not a PNG vt can mark"));
        }
        let mut body = b"tEXt".to_vec();
        body.extend_from_slice(b"Comment\0");
        body.extend_from_slice(marker.as_bytes());
        let mut chunk = ((body.len() - 4) as u32).to_be_bytes().to_vec();
        chunk.extend_from_slice(&body);
        chunk.extend_from_slice(&crc32fast::hash(&body).to_be_bytes());
        data.splice(ihdr_end..ihdr_end, chunk);
        std::fs::write(path, data).map_err(io)
    } else if n >= 2 && head[..2] == [0xFF, 0xD8] {
        let mut data = Vec::new();
        f.seek(SeekFrom::Start(0)).map_err(io)?;
        f.read_to_end(&mut data).map_err(io)?;
        let mut seg = vec![0xFF, 0xFE];
        seg.extend_from_slice(&((marker.len() + 2) as u16).to_be_bytes());
        seg.extend_from_slice(marker.as_bytes());
        data.splice(2..2, seg);
        std::fs::write(path, data).map_err(io)
    } else if n >= 6 && (&head[..6] == b"GIF89a" || &head[..6] == b"GIF87a") {
        let len = f.metadata().map_err(io)?.len();
        let mut last = [0u8; 1];
        f.seek(SeekFrom::Start(len.saturating_sub(1))).map_err(io)?;
        f.read_exact(&mut last).map_err(io)?;
        if last[0] != 0x3B {
            return Err(out_err(path, "GIF without its trailer"));
        }
        f.seek(SeekFrom::Start(len - 1)).map_err(io)?;
        f.write_all(&gif_comment(&marker)).map_err(io)
    } else if contains_marker(path, &marker)? {
        Ok(())
    } else {
        Err(out_err(path, "vt could not mark this file as its output"))
    }
}

pub(super) fn gif_comment(marker: &str) -> Vec<u8> {
    let mut v = vec![0x21, 0xFE, marker.len() as u8];
    v.extend_from_slice(marker.as_bytes());
    v.extend_from_slice(&[0x00, 0x3B]);
    v
}

/// Whether a file carries vt's marker of `kind` for itself, where it is (see [`embed_marker`]):
/// false for a copy of a vt output, or one moved from another name.
pub fn has_marker(path: &Path, kind: OutputKind) -> Result<bool> {
    contains_marker(path, &kind.marker(&identity(path, path)?))
}

/// Whether a file carries the marker text `marker` where its format keeps vt's marker.
pub(super) fn contains_marker(path: &Path, marker: &str) -> Result<bool> {
    let io = |e| Error::io(path, e);
    let mut f = std::fs::File::open(path).map_err(io)?;
    let len = f.metadata().map_err(io)?.len();
    let mut head = vec![0u8; 64 << 10];
    let n = read_up_to(&mut f, &mut head).map_err(io)?;
    head.truncate(n);
    if head.starts_with(b"# ") {
        // A text file: the marker is its first line, as a comment.
        let line = head.split(|&b| b == b'\n').next().unwrap_or_default();
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        return Ok(line.strip_prefix(b"# ") == Some(marker.as_bytes()));
    }
    if head.starts_with(b"\x89PNG") {
        // tEXt chunks before IDAT; vt puts its own right after IHDR.
        let mut o = 8usize;
        while o + 8 <= head.len() {
            let l = u32::from_be_bytes(head[o..o + 4].try_into().expect("4 bytes")) as usize;
            let t = &head[o + 4..o + 8];
            if t == b"IDAT" {
                break;
            }
            let end = o.saturating_add(8).saturating_add(l);
            if t == b"tEXt" && end <= head.len() {
                let body = &head[o + 8..end];
                if body.strip_prefix(b"Comment\0") == Some(marker.as_bytes()) {
                    return Ok(true);
                }
            }
            o = end.saturating_add(4);
        }
        return Ok(false);
    }
    if head.starts_with(&[0xFF, 0xD8]) {
        let mut seg = vec![0xFF, 0xFE];
        seg.extend_from_slice(&((marker.len() + 2) as u16).to_be_bytes());
        seg.extend_from_slice(marker.as_bytes());
        return Ok(head[2..].starts_with(&seg));
    }
    if head.starts_with(b"GIF8") {
        let tail = gif_comment(marker);
        if len < tail.len() as u64 {
            return Ok(false);
        }
        let mut buf = vec![0u8; tail.len()];
        f.seek(SeekFrom::Start(len - tail.len() as u64))
            .map_err(io)?;
        f.read_exact(&mut buf).map_err(io)?;
        return Ok(buf == tail);
    }
    if head.len() >= 8 && &head[4..8] == b"ftyp" {
        // MP4: find the top-level moov box and look for the comment in it.
        let mut o = 0u64;
        while o + 8 <= len {
            let mut hdr = [0u8; 16];
            f.seek(SeekFrom::Start(o)).map_err(io)?;
            let got = read_up_to(&mut f, &mut hdr).map_err(io)?;
            if got < 8 {
                break;
            }
            let mut size = u32::from_be_bytes(hdr[..4].try_into().expect("4 bytes")) as u64;
            let mut body = 8;
            if size == 1 && got >= 16 {
                size = u64::from_be_bytes(hdr[8..16].try_into().expect("8 bytes"));
                body = 16;
            } else if size == 0 {
                size = len - o;
            }
            if size < body {
                break;
            }
            if &hdr[4..8] == b"moov" {
                let take = (size - body).min(64 << 20);
                let mut moov = Vec::new();
                f.seek(SeekFrom::Start(o + body)).map_err(io)?;
                (&mut f).take(take).read_to_end(&mut moov).map_err(io)?;
                return Ok(moov.windows(marker.len()).any(|w| w == marker.as_bytes()));
            }
            o = o.saturating_add(size);
        }
        return Ok(false);
    }
    Ok(false)
}

pub(super) fn read_up_to(f: &mut std::fs::File, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match f.read(&mut buf[n..])? {
            0 => break,
            k => n += k,
        }
    }
    Ok(n)
}
