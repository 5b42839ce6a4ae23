//! Photos and their silhouettes as loaded: mask files, alpha, threshold or backdrop.

use super::*;

/// Downscales a mask: a pixel is set when any full-size pixel under it is.
pub fn scale_mask(m: &Mask, w: u32, h: u32) -> Mask {
    let (sx, sy) = (m.width() as f64 / w as f64, m.height() as f64 / h as f64);
    Mask::from_fn(w, h, |x, y| {
        let (x0, x1) = (
            (x as f64 * sx).floor() as i64,
            ((x + 1) as f64 * sx).ceil() as i64,
        );
        let (y0, y1) = (
            (y as f64 * sy).floor() as i64,
            ((y + 1) as f64 * sy).ceil() as i64,
        );
        (y0..y1.max(y0 + 1)).any(|yy| (x0..x1.max(x0 + 1)).any(|xx| m.get_or_false(xx, yy)))
    })
}

/// A supplied silhouette image: non-zero = object, the size of its photo.
pub(super) fn read_mask(
    path: &Path,
    name: &str,
    size: (u32, u32),
    photo: &Path,
) -> Result<Mask, DataError> {
    if !path.is_file() {
        return Err(path_err(path, format!("mask for image {name} is missing")));
    }
    let bytes = vt_io::limits::read_bytes(path, vt_io::limits::MAX_IMAGE_FILE_BYTES, "mask image")?;
    let m = image::load_from_memory(&bytes)
        .map_err(|e| path_err(path, e.to_string()))?
        .to_luma8();
    if m.dimensions() != size {
        return Err(path_err(
            path,
            format!(
                "mask is {}x{} but image {} is {}x{}",
                m.width(),
                m.height(),
                photo.display(),
                size.0,
                size.1
            ),
        ));
    }
    Ok(mask_from_image(&m))
}

/// Where one view's silhouette came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum SilhouetteKind {
    /// A mask image in the masks folder.
    Masks,
    /// The photo's alpha channel.
    Alpha,
    /// The dark-backdrop threshold.
    Dark,
    /// The plain-backdrop segmentation.
    Backdrop,
}

/// A photo, and its alpha channel as a mask (alpha >= 128 = object) when it has one that is not
/// fully opaque. Decoded through vt-io's limits.
pub(super) fn read_photo(
    path: &Path,
    background: Option<[u8; 3]>,
) -> Result<(RgbImage, Option<Mask>), DataError> {
    let bytes = vt_io::limits::read_bytes(path, vt_io::limits::MAX_IMAGE_FILE_BYTES, "image file")?;
    let rgb = vt_io::frames::decode_rgb(&bytes, path)?;
    let has_alpha = image::ImageReader::new(std::io::Cursor::new(&bytes))
        .with_guessed_format()
        .ok()
        .and_then(|r| r.into_decoder().ok())
        .is_some_and(|d| image::ImageDecoder::color_type(&d).has_alpha());
    if !has_alpha {
        return Ok((rgb, None));
    }
    // The same bytes decode_rgb accepted (its size limits hold), now keeping the alpha.
    let rgba = image::load_from_memory(&bytes)
        .map_err(|e| path_err(path, e.to_string()))?
        .to_rgba8();
    let a = rgba.as_raw();
    if a.chunks_exact(4).all(|p| p[3] == 255) {
        return Ok((rgb, None));
    }
    let m = Mask::from_index_fn(rgba.width(), rgba.height(), |i| a[4 * i + 3] >= 128);
    if m.count_ones() == 0 {
        return Err(path_err(
            path,
            "its alpha channel is transparent everywhere (below 128): no object in the mask",
        ));
    }
    let rgb = match background {
        None => rgb,
        Some(bg) => crate::composite::over(&rgba, bg),
    };
    Ok((rgb, Some(m)))
}

/// The silhouettes' origin in words; photos with an alpha mask beside photos without are
/// refused (naming both).
pub(super) fn describe_silhouettes(
    kinds: &[SilhouetteKind],
    mask_dir: Option<&Path>,
    opt: &DataOptions,
    sources: &[Source],
) -> Result<String, DataError> {
    if let Some(d) = mask_dir {
        return Ok(format!("mask images in {}", d.display()));
    }
    let count = |k| kinds.iter().filter(|&&x| x == k).count();
    let n = kinds.len();
    let alpha = count(SilhouetteKind::Alpha);
    if alpha > 0 && alpha < n {
        let with = kinds
            .iter()
            .position(|&k| k == SilhouetteKind::Alpha)
            .unwrap_or(0);
        let without = kinds
            .iter()
            .position(|&k| k != SilhouetteKind::Alpha)
            .unwrap_or(0);
        return Err(path_err(
            &sources[without].photo,
            format!(
                "has no transparency, but {} carries its silhouette in its alpha channel: give every photo an alpha mask, or none",
                sources[with].photo.display()
            ),
        ));
    }
    if alpha == n {
        return Ok("the photos' alpha channels (alpha >= 128 = object)".into());
    }
    let dark = format!(
        "photos thresholded (carving: at {}, dilate {}, erode {}; scoring: at {}, dilate {}, erode {})",
        opt.threshold, opt.carve_dilate, opt.carve_erode, opt.score.threshold, opt.score.dilate, opt.score.erode
    );
    let plain =
        "photos segmented from their plain backdrop (colour estimated from each photo's border)";
    Ok(match count(SilhouetteKind::Dark) {
        0 => plain.to_string(),
        d if d == n => dark,
        d => format!("{d} of {n} {dark}; {} of {n} {plain}", n - d),
    })
}

pub(super) fn range(v: &[f64]) -> String {
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if (hi - lo).abs() < 5e-5 {
        format!("{lo:.4}")
    } else {
        format!("{lo:.4}-{hi:.4}")
    }
}
