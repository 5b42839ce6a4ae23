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

/// How the first line of a points file vt wrote begins ([`write_points_file`]): vt's marker as a
/// comment, recording the very file ([`crate::output`]'s rules), so a later save may replace it
/// and nothing else.
pub const OUTPUT_MARKER: &str = "# vt-output points";

/// Checks that [`write_points_file`] may write `path` ([`crate::output::check_target`]): its
/// folder exists, it is none of `inputs`, and whatever is there already is the points file vt
/// wrote there, not a link, a folder, a copy or anyone else's file.
pub fn check_points_output(path: &Path, inputs: &[&Path]) -> Result<()> {
    crate::output::check_target(path, crate::output::OutputKind::Points, inputs)
}

/// Writes a points file of `views` (every view the same K >= 4 finite points) at `path` through
/// [`crate::output::Output`] (checked as [`check_points_output`] says, written to a temporary
/// sibling and renamed into place, so the file is either whole or untouched). The first line is
/// vt's marker (it begins [`OUTPUT_MARKER`]), then [`format_points`]'s text.
pub fn write_points_file(path: &Path, views: &[Vec<Point>], inputs: &[&Path]) -> Result<()> {
    let err = |message: String| Error::Points {
        path: path.to_path_buf(),
        line: 0,
        message,
    };
    let k = views.first().map_or(0, Vec::len);
    if views.is_empty() || k < 4 {
        return Err(err(format!("{k} points; a homography needs at least 4")));
    }
    if let Some(p) = views.iter().position(|v| v.len() != k) {
        let n = views[p].len();
        return Err(err(format!("view {p} has {n} points, view 0 has {k}")));
    }
    if views
        .iter()
        .flatten()
        .any(|q| !(q.x.is_finite() && q.y.is_finite()))
    {
        return Err(err("a point is not finite".into()));
    }
    let out = crate::output::Output::file(path, crate::output::OutputKind::Points, inputs)?;
    let written = std::fs::File::create(out.path()).and_then(|mut f| {
        std::io::Write::write_all(&mut f, format_points(views).as_bytes())?;
        f.sync_all()
    });
    written.map_err(|e| Error::io(out.path(), e))?;
    out.commit().map(|_| ())
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
    fn writes_only_its_own_files() {
        let dir = std::env::temp_dir().join(format!("vt-points-writer-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let v = vec![
            vec![
                Point::new(1.0, 2.0),
                Point::new(3.0, 4.5),
                Point::new(5.0, 6.0),
                Point::new(7.0, 8.25),
            ];
            2
        ];
        let out = dir.join("p.txt");
        write_points_file(&out, &v, &[]).unwrap();
        assert_eq!(read_points(&out).unwrap(), v);
        // Its own file is replaced; a user's file, a folder and an input are not.
        write_points_file(&out, &v, &[]).unwrap();
        let user = dir.join("mine.txt");
        std::fs::write(&user, "1 2 3 4 5 6 7 8\n").unwrap();
        let e = write_points_file(&user, &v, &[]).unwrap_err().to_string();
        assert!(e.contains("not a vt points output"), "{e}");
        assert_eq!(std::fs::read_to_string(&user).unwrap(), "1 2 3 4 5 6 7 8\n");
        let e = write_points_file(&dir, &v, &[]).unwrap_err().to_string();
        assert!(e.contains("(a folder with"), "{e}");
        // A copy of vt's own points file is not vt's output there.
        let copy = dir.join("copy.txt");
        std::fs::copy(&out, &copy).unwrap();
        let e = write_points_file(&copy, &v, &[]).unwrap_err().to_string();
        assert!(e.contains("not a vt points output written here"), "{e}");
        std::fs::remove_file(&copy).unwrap();
        let e = write_points_file(&out, &v, &[&out])
            .unwrap_err()
            .to_string();
        assert!(e.contains("one of this run's inputs"), "{e}");
        let e = write_points_file(&out, &[v[0][..3].to_vec()], &[]).unwrap_err();
        assert!(e.to_string().contains("3 points"), "{e}");
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 2, "no temporary left: {names:?}");
        std::fs::remove_dir_all(&dir).unwrap();
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
