//! 4:2:0 to RGB: vt-core's conversion against OpenCV's `cvtColor(COLOR_YUV2RGB_I420)`, on
//! random planes (every byte value, widths with and without a partial block) and on real video
//! frames (tree.avi encoded to H.264 and decoded as 4:2:0 by vt-io, as the analysis reads them).

#[allow(unused_imports)]
use super::*;
use vt_core::analysis::FrameRef;
use vt_core::yuv::{Yuv420Image, YuvMatrix, YuvRange};

fn compare(t: &mut Table, input: &str, img: &Yuv420Image) {
    let vt = img.to_rgb();
    match vt_cv::yuv::yuv420_to_rgb(img) {
        Ok(cv) => {
            let differ = vt
                .as_raw()
                .iter()
                .zip(cv.as_raw())
                .filter(|(a, b)| a != b)
                .count();
            t.add_images(
                "yuv420 to RGB",
                input,
                format!("{differ} bytes differ"),
                "identical",
                differ == 0,
                (&vt, &cv),
            );
        }
        Err(e) => t.error("yuv420 to RGB", input, e),
    }
}

pub(super) fn yuv(t: &mut Table) -> Result<()> {
    for (w, h, seed) in [(38u32, 26u32, 1u64), (640, 360, 2), (1918, 1080, 3)] {
        let mut rng = vt_core::rng::Rng::new(seed);
        let data = (0..Yuv420Image::byte_len(w, h))
            .map(|_| rng.next_u64() as u8)
            .collect();
        let img = Yuv420Image::from_raw(w, h, YuvMatrix::Bt601, YuvRange::Limited, data)?;
        compare(t, &format!("random planes {w}x{h}"), &img);
    }
    if !vt_io::video::ffmpeg_available() {
        t.error(
            "yuv420 to RGB",
            "tree.avi as H.264",
            "ffmpeg is not installed",
        );
        return Ok(());
    }
    // tree.avi re-encoded to H.264 (4:2:0), decoded as the analysis decodes it.
    let path = testdata().join("tree.avi");
    let frames = vt_io::frames::ViewSource::open(&path)?.read_all()?;
    let dir = std::env::temp_dir().join(format!("vt-cross-check-yuv-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let mp4 = dir.join("tree.mp4");
    let n = frames.len().min(10);
    let (w, h) = frames[0].dimensions();
    vt_io::video::encode_h264(&mp4, w, h, 10.0, 18, n, &mut |i| Ok(frames[i].clone()))?;
    let mut src = vt_io::frames::VideoSource::open(&mp4)?;
    let mut decoded = Vec::new();
    let read = src.for_each_native(&mut |_, f| {
        if let FrameRef::Yuv420(y) = f {
            decoded.push(y.clone());
        }
        Ok(())
    });
    let _ = std::fs::remove_dir_all(&dir);
    read?;
    if decoded.len() != n {
        bail!(
            "{}: {} of {n} frames decoded as 4:2:0",
            mp4.display(),
            decoded.len()
        );
    }
    for (i, img) in decoded.iter().enumerate().step_by(3) {
        compare(t, &format!("tree.avi as H.264, frame {i}"), img);
    }
    Ok(())
}
