//! The points file: the marked correspondence points of every view (SPEC "Inputs").
//!
//! Plain text, one line per view in view order, each line the same K >= 4 points as `x y` pairs
//! in pixels (origin top-left, pixel centres at integers). `#` starts a comment; blank lines are
//! skipped. Example for two views and four points:
//!
//! ```text
//! # vt points: one line per view; x y pairs
//! 100.5 80  300 82.25  298 240  102 238
//! 121.5 80  321 82.25  319 240  123 238
//! ```

use std::path::Path;

use vt_core::Point;

use crate::{Error, Result};

/// Parses a points file's text. `path` is only used in messages.
pub fn parse_points(text: &str, path: &Path) -> Result<Vec<Vec<Point>>> {
    let err = |line: usize, message: String| Error::Points {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut views = Vec::new();
    let mut first: Option<(usize, usize)> = None;
    for (i, raw) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let mut nums = Vec::new();
        for tok in line
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|t| !t.is_empty())
        {
            let short = crate::output::shorten(tok);
            let v: f64 = tok
                .parse()
                .map_err(|_| err(line_no, format!("'{short}' is not a number")))?;
            if !v.is_finite() {
                return Err(err(line_no, format!("'{short}' is not a finite number")));
            }
            if nums.len() >= 2 * crate::limits::MAX_POINTS {
                return Err(err(
                    line_no,
                    format!(
                        "more than {} points (the most vt reads per view)",
                        crate::limits::MAX_POINTS
                    ),
                ));
            }
            nums.push(v);
        }
        if nums.len() % 2 != 0 {
            return Err(err(
                line_no,
                format!("{} numbers: points need x y pairs", nums.len()),
            ));
        }
        let k = nums.len() / 2;
        if k < 4 {
            return Err(err(
                line_no,
                format!("{k} points; a homography needs at least 4"),
            ));
        }
        match first {
            None => first = Some((line_no, k)),
            Some((l0, k0)) if k0 != k => {
                return Err(err(
                    line_no,
                    format!("{k} points, but line {l0} has {k0}: every view marks the same points"),
                ))
            }
            _ => {}
        }
        if views.len() >= crate::limits::MAX_VIEWS {
            return Err(err(
                line_no,
                format!(
                    "more than {} views (the most vt reads)",
                    crate::limits::MAX_VIEWS
                ),
            ));
        }
        views.push(nums.chunks(2).map(|c| Point::new(c[0], c[1])).collect());
    }
    if views.is_empty() {
        return Err(err(
            0,
            "no points: expected one line of x y pairs per view".into(),
        ));
    }
    Ok(views)
}

/// Reads and parses a points file.
pub fn read_points(path: &Path) -> Result<Vec<Vec<Point>>> {
    let text = crate::limits::read_text(path, crate::limits::MAX_TEXT_BYTES, "points file")?;
    parse_points(&text, path)
}

/// How far beyond the frame's edges a marked point may lie, as a fraction of the frame's side.
pub const POINT_MARGIN: f64 = 0.1;

/// Reads the points file of `n_views` views of `size` (width, height): one line per view, and
/// every point inside the frame or at most [`POINT_MARGIN`] of its side beyond an edge.
pub fn read_for_views(path: &Path, n_views: usize, size: (u32, u32)) -> Result<Vec<Vec<Point>>> {
    let err = |message: String| Error::Points {
        path: path.to_path_buf(),
        line: 0,
        message,
    };
    let points = read_points(path)?;
    if points.len() != n_views {
        return Err(err(format!(
            "{} lines of points, but {n_views} views were given (one line per view)",
            points.len()
        )));
    }
    let (w, h) = (size.0 as f64, size.1 as f64);
    let (mx, my) = (POINT_MARGIN * w, POINT_MARGIN * h);
    for (p, view) in points.iter().enumerate() {
        for (k, pt) in view.iter().enumerate() {
            if pt.x < -0.5 - mx || pt.x > w - 0.5 + mx || pt.y < -0.5 - my || pt.y > h - 0.5 + my {
                return Err(err(format!(
                    "view {p} point {k} ({}, {}) is outside the {}x{} frame (at most {:.0}% beyond its edges)",
                    crate::output::num(pt.x),
                    crate::output::num(pt.y),
                    size.0,
                    size.1,
                    100.0 * POINT_MARGIN
                )));
            }
        }
    }
    Ok(points)
}

/// Formats points in the file format (3 decimals).
pub fn format_points(views: &[Vec<Point>]) -> String {
    let mut s = String::from(
        "# vt points: one line per view, in view order; x y pairs in pixels (origin top-left)\n",
    );
    for v in views {
        let line: Vec<String> = v.iter().map(|p| format!("{:.3} {:.3}", p.x, p.y)).collect();
        s.push_str(&line.join("  "));
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(text: &str, want: &str) {
        let got = parse_points(text, Path::new("p.txt"))
            .map(|v| v.len().to_string())
            .unwrap_or_else(|e| e.to_string());
        assert_eq!(got, want, "input: {text:?}");
    }

    #[test]
    fn cases() {
        check("# c\n1 2 3 4 5 6 7 8\n\n1 2 3 4 5 6 7 9 # x\n", "2");
        check("1,2, 3,4, 5,6, 7,8\n", "1");
        check(
            "1 2 3 4 5 6 7 nan\n",
            "p.txt:1: 'nan' is not a finite number",
        );
        check(
            "1 2 3 4 5 6 7 inf\n",
            "p.txt:1: 'inf' is not a finite number",
        );
        check("1 2 3 4 5 6 7 x\n", "p.txt:1: 'x' is not a number");
        check(
            "1 2 3 4 5 6\n",
            "p.txt:1: 3 points; a homography needs at least 4",
        );
        check(
            "1 2 3 4 5 6 7\n",
            "p.txt:1: 7 numbers: points need x y pairs",
        );
        check(
            "1 2 3 4 5 6 7 8\n1 2 3 4 5 6 7 8 9 10\n",
            "p.txt:2: 5 points, but line 1 has 4: every view marks the same points",
        );
        check(
            "# nothing\n",
            "p.txt: no points: expected one line of x y pairs per view",
        );
    }

    #[test]
    fn round_trip() {
        let v = vec![vec![
            Point::new(1.25, 2.0),
            Point::new(3.0, 4.5),
            Point::new(5.0, 6.0),
            Point::new(7.0, 8.125),
        ]];
        assert_eq!(parse_points(&format_points(&v), Path::new("x")).unwrap(), v);
    }
}
