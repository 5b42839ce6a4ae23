//! Viewpoint paths for rendering: the `--path` format, sampled to one viewpoint per output frame.
//!
//! - `T0s:Q0,T1s:Q1,...`: keyframes (seconds : viewpoint), linear in between, held after the last;
//! - `sweep[:SPEED]`: from view 0 to M-1 and back at SPEED views per second (default 1);
//! - `@FILE`: one viewpoint per line (`#` comments), one per frame.
//!
//! Every length is checked against the limits below before the path is built, so an absurd
//! duration or speed is a clear error, never an allocation.

use std::path::Path;

use crate::output::{num, shorten};
use crate::{Error, Result};

/// `return Err(Error::Param(format!(...)))`.
macro_rules! param {
    ($($t:tt)*) => {
        Err(Error::Param(format!($($t)*)))
    };
}

/// `Error::Param(format!(...))`.
macro_rules! param_err {
    ($($t:tt)*) => {
        Error::Param(format!($($t)*))
    };
}

/// Longest render without `--long`, seconds of output.
pub const MAX_SECONDS: f64 = 600.0;
/// Longest render with `--long`, seconds of output (a day).
pub const MAX_SECONDS_LONG: f64 = 86_400.0;
/// Most frames of any render (a day at 60 fps); the path is checked against it before it is
/// built.
pub const MAX_FRAMES: usize = 5_184_000;

/// A viewpoint path, sampled per output frame. Its length is checked (at most [`MAX_SECONDS`] of
/// output, [`MAX_SECONDS_LONG`] with `long`, and [`MAX_FRAMES`] frames) before any of it is built.
pub fn viewpoints(
    spec: &str,
    n_views: usize,
    fps: f64,
    duration: Option<f64>,
    long: bool,
) -> Result<Vec<f64>> {
    if !(fps.is_finite() && fps > 0.0 && fps <= 1000.0) {
        return param!("--fps {} must be in (0, 1000]", num(fps));
    }
    let max_secs = if long { MAX_SECONDS_LONG } else { MAX_SECONDS };
    let hint = if long {
        "the most vt renders"
    } else {
        "the most vt renders without --long (up to 86400 s with it)"
    };
    if let Some(d) = duration {
        if !(d.is_finite() && d > 0.0) {
            return param!("--duration {} must be a positive number of seconds", num(d));
        }
        if d > max_secs {
            return param!(
                "--duration {} s is longer than {max_secs} s, {hint}",
                num(d)
            );
        }
    }
    let q_max = n_views.saturating_sub(1) as f64;
    // Frames of `secs` seconds, checked against the limits before anything is allocated.
    let frames = |secs: f64, what: &str| -> Result<usize> {
        if !(secs.is_finite() && secs <= max_secs) {
            return param!("{what} is {secs:.4e} s long, longer than {max_secs} s, {hint}");
        }
        let n = (secs * fps).round().max(1.0);
        if n > MAX_FRAMES as f64 {
            return param!(
                "{what} is {n} frames at {} fps, more than {MAX_FRAMES}",
                num(fps)
            );
        }
        Ok(n as usize)
    };
    let check_q = |q: f64, what: &str| -> Result<f64> {
        if !q.is_finite() || q < 0.0 || q > q_max {
            return param!(
                "--path: {what}: viewpoint {} is outside [0, {q_max}] (the scene has {n_views} views)",
                num(q)
            );
        }
        Ok(q)
    };
    if let Some(file) = spec.strip_prefix('@') {
        let text = crate::limits::read_text(
            Path::new(file),
            crate::limits::MAX_TEXT_BYTES,
            "viewpoint file",
        )?;
        let max_lines = if long {
            MAX_FRAMES
        } else {
            (MAX_SECONDS * fps) as usize
        };
        let mut qs = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let t = line.split('#').next().unwrap_or("").trim();
            if t.is_empty() {
                continue;
            }
            let q: f64 = t
                .parse()
                .map_err(|_| param_err!("{file}:{}: '{}' is not a number", i + 1, shorten(t)))?;
            qs.push(check_q(q, &format!("{file}:{}", i + 1))?);
            if qs.len() > max_lines {
                return param!("{file}: more than {max_lines} viewpoints (one per frame), {hint}");
            }
        }
        if qs.is_empty() {
            return param!("{file}: no viewpoints (one q per line)");
        }
        if let Some(d) = duration {
            let n = frames(d, "--duration")?;
            let last = *qs.last().expect("non-empty");
            qs.resize(n, last);
        }
        return Ok(qs);
    }
    if let Some(rest) = spec.strip_prefix("sweep") {
        let speed = match rest.strip_prefix(':') {
            Some(s) => s
                .parse::<f64>()
                .map_err(|_| param_err!("--path sweep:{}: speed is not a number", shorten(s)))?,
            None if rest.is_empty() => 1.0,
            None => return param!("--path '{}': expected sweep or sweep:SPEED", shorten(spec)),
        };
        if !(speed.is_finite() && speed > 0.0) {
            return param!(
                "--path sweep:{}: speed must be positive (views per second)",
                num(speed)
            );
        }
        let one_way = if q_max > 0.0 { q_max / speed } else { 1.0 };
        let n = match duration {
            Some(d) => frames(d, "--duration")?,
            None => frames(2.0 * one_way, &format!("--path sweep:{}", num(speed)))?,
        };
        return Ok((0..n)
            .map(|i| {
                let t = (i as f64 / fps) % (2.0 * one_way);
                let q = if t <= one_way {
                    t * speed
                } else {
                    (2.0 * one_way - t) * speed
                };
                q.clamp(0.0, q_max)
            })
            .collect());
    }
    let mut keys: Vec<(f64, f64)> = Vec::new();
    for part in spec.split(',') {
        let (t, q) = part.split_once(':').ok_or_else(|| {
            param_err!(
                "--path: '{}' is not TIME:Q (e.g. 0s:0,4s:14,8s:0)",
                shorten(part)
            )
        })?;
        let t = t.trim().trim_end_matches('s');
        let t: f64 = t
            .parse()
            .map_err(|_| param_err!("--path: time '{}' is not a number of seconds", shorten(t)))?;
        let q: f64 = q
            .trim()
            .parse()
            .map_err(|_| param_err!("--path: viewpoint '{}' is not a number", shorten(q)))?;
        if !t.is_finite() || t < 0.0 || keys.last().is_some_and(|&(pt, _)| t <= pt) {
            return param!(
                "--path: keyframe times must be finite, >= 0 and increasing ('{}')",
                shorten(part)
            );
        }
        keys.push((t, check_q(q, &shorten(part))?));
    }
    let end = keys.last().map(|k| k.0).unwrap_or(0.0);
    let n = match duration {
        Some(d) => frames(d, "--duration")?,
        None => frames(end.max(1.0 / fps), "--path")?,
    };
    Ok((0..n)
        .map(|i| {
            let t = i as f64 / fps;
            match keys.iter().position(|k| k.0 > t) {
                None => keys[keys.len() - 1].1,
                Some(0) => keys[0].1,
                Some(k) => {
                    let ((t0, q0), (t1, q1)) = (keys[k - 1], keys[k]);
                    q0 + (q1 - q0) * (t - t0) / (t1 - t0)
                }
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths() {
        let qs = viewpoints("0s:0,1s:2,2s:2", 3, 4.0, None, false).unwrap();
        assert_eq!(qs, vec![0.0, 0.5, 1.0, 1.5, 2.0, 2.0, 2.0, 2.0]);
        let sweep = viewpoints("sweep:2", 3, 2.0, None, false).unwrap();
        assert_eq!(sweep, vec![0.0, 1.0, 2.0, 1.0]);
        assert_eq!(
            viewpoints("sweep", 1, 10.0, Some(0.5), false).unwrap(),
            vec![0.0; 5]
        );
        for (bad, want) in [
            ("0s:0,1s:5", "outside [0, 2]"),
            ("0s:0,0s:1", "increasing"),
            ("zero", "TIME:Q"),
            ("sweep:-1", "positive"),
            ("sweep:x", "not a number"),
            ("sweep:1e-300", "longer than 600 s"),
            ("0s:0,1e9s:1", "longer than 600 s"),
        ] {
            let e = viewpoints(bad, 3, 30.0, None, false)
                .unwrap_err()
                .to_string();
            assert!(e.contains(want), "{bad}: {e}");
        }
    }
}
