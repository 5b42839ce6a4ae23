//! Homography agreement and stability rows.

#[allow(unused_imports)]
use super::*;

/// Agreement on well-conditioned points: both sides get the same f32-rounded points.
pub(super) fn homography_agreement(
    t: &mut Table,
    input: &str,
    src: &[Point],
    dst: &[Point],
    truth: Option<&Matrix3<f64>>,
) {
    let (s32, d32) = (round_f32(src), round_f32(dst));
    let op = if src.len() == 4 {
        "homography (4 pts, getPerspectiveTransform)"
    } else {
        "homography (findHomography 0)"
    };
    let vt = Homography::from_correspondences(&s32, &d32);
    let cv = vt_cv::homography::from_correspondences(&s32, &d32);
    match (vt, cv) {
        (Ok(vt), Ok(cv)) => {
            let (mv, mc) = (vt.homography.matrix(), cv.homography.matrix());
            let rel = h_rel_diff(&mv, &mc);
            let truth_txt = truth
                .map(|h| {
                    format!(
                        ", vs truth vt {:.1e} cv {:.1e}",
                        h_rel_diff(&mv, h),
                        h_rel_diff(&mc, h)
                    )
                })
                .unwrap_or_default();
            t.add(
                op,
                input,
                format!(
                    "rel diff {rel:.2e} (rms vt {:.2e} cv {:.2e}{truth_txt})",
                    vt.rms, cv.rms
                ),
                "<= 1e-6",
                rel <= 1e-6,
            );
        }
        (vt, cv) => t.add(
            op,
            input,
            format!("vt {:?} / cv {:?}", vt.map(|f| f.rms), cv.map(|f| f.rms)),
            "both succeed",
            false,
        ),
    }
}

/// Stability: vt-core on the original points never worse than OpenCV, never non-finite.
pub(super) fn homography_stability(t: &mut Table, input: &str, src: &[Point], dst: &[Point]) {
    let vt: Result<HomographyFit, _> = Homography::from_correspondences(src, dst);
    let cv = vt_cv::homography::estimate_matrix(src, dst);
    let cv_rms = cv
        .as_ref()
        .map(|m| rms(m, src, dst))
        .unwrap_or(f64::INFINITY);
    let cv_txt = match &cv {
        Ok(_) => format!("cv rms {cv_rms:.2e}"),
        Err(_) => "cv error".to_string(),
    };
    match vt {
        Ok(fit) => {
            let m = fit.homography.matrix();
            let vt_rms = rms(&m, src, dst);
            let finite =
                m.iter().all(|v| v.is_finite()) && vt_rms.is_finite() && fit.rms.is_finite();
            let ok = finite && vt_rms <= cv_rms * (1.0 + 1e-9) + 1e-12;
            t.add(
                "homography stability",
                input,
                format!("vt rms {vt_rms:.2e}, {cv_txt}"),
                "finite, vt <= cv (1e-9 rel)",
                ok,
            );
        }
        Err(e) => {
            // An error is an acceptable answer; say which one and what OpenCV did instead.
            let msg = e.to_string();
            let short: String = msg.chars().take(48).collect();
            t.add(
                "homography stability",
                input,
                format!("vt Err ({short}...), {cv_txt}"),
                "finite, vt <= cv (1e-9 rel)",
                true,
            );
        }
    }
}
