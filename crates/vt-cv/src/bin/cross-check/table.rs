//! The result table: one row per check, printed at the end.

#[allow(unused_imports)]
use super::*;

/// One line of the table.
pub(super) struct Row {
    pub(super) op: String,
    pub(super) input: String,
    pub(super) figure: String,
    pub(super) tolerance: String,
    pub(super) pass: bool,
}

#[derive(Default)]
pub(super) struct Table {
    pub(super) rows: Vec<Row>,
}

impl Table {
    pub(super) fn add(
        &mut self,
        op: &str,
        input: &str,
        figure: impl Into<String>,
        tolerance: &str,
        pass: bool,
    ) {
        let row = Row {
            op: op.into(),
            input: input.into(),
            figure: figure.into(),
            tolerance: tolerance.into(),
            pass,
        };
        self.rows.push(row);
    }

    /// [`Table::add`] for a row comparing two images: on failure it writes the vt-core image,
    /// the OpenCV image and their difference (x8, so one grey level shows) as PNGs under
    /// `target/cross-check/` and names the files in the row, so the failure can be looked at.
    pub(super) fn add_images(
        &mut self,
        op: &str,
        input: &str,
        figure: impl Into<String>,
        tolerance: &str,
        pass: bool,
        (vt, cv): (&RgbImage, &RgbImage),
    ) {
        let mut figure = figure.into();
        if !pass {
            match save_diff(op, input, vt, cv) {
                Ok(path) => figure.push_str(&format!(" (diff: {})", path.display())),
                Err(e) => figure.push_str(&format!(" (diff not written: {e:#})")),
            }
        }
        self.add(op, input, figure, tolerance, pass);
    }

    /// Records an error from either side as a failed row (the run goes on).
    pub(super) fn error(&mut self, op: &str, input: &str, e: impl std::fmt::Display) {
        self.add(op, input, format!("error: {e}"), "no error", false);
    }

    pub(super) fn print(&self) {
        let head = ["operation", "input", "figure", "tolerance", "pass/fail"];
        let cells: Vec<[String; 5]> = self
            .rows
            .iter()
            .map(|r| {
                [
                    r.op.clone(),
                    r.input.clone(),
                    r.figure.clone(),
                    r.tolerance.clone(),
                    (if r.pass { "pass" } else { "FAIL" }).into(),
                ]
            })
            .collect();
        let mut width = head.map(str::len);
        for c in &cells {
            for i in 0..5 {
                width[i] = width[i].max(c[i].chars().count());
            }
        }
        let line = |c: &[String; 5]| {
            let parts: Vec<String> = (0..5)
                .map(|i| format!("{:<w$}", c[i], w = width[i]))
                .collect();
            println!("| {} |", parts.join(" | "));
        };
        line(&head.map(String::from));
        let sep: Vec<String> = width.iter().map(|w| "-".repeat(*w)).collect();
        println!("|-{}-|", sep.join("-|-"));
        for c in &cells {
            line(c);
        }
    }
}

/// Writes `<op>-<input>-{vt,cv,diff}.png` into `target/cross-check/`; returns the diff's path.
fn save_diff(op: &str, input: &str, vt: &RgbImage, cv: &RgbImage) -> Result<PathBuf> {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target"));
    let dir = target.join("cross-check");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let slug: String = format!("{op}-{input}")
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    let (w, h) = (vt.width().min(cv.width()), vt.height().min(cv.height()));
    let diff = RgbImage::from_fn(w, h, |x, y| {
        let (a, b) = (vt.get_pixel(x, y).0, cv.get_pixel(x, y).0);
        image::Rgb([0, 1, 2].map(|c| a[c].abs_diff(b[c]).saturating_mul(8)))
    });
    for (name, img) in [("vt", vt), ("cv", cv), ("diff", &diff)] {
        let path = dir.join(format!("{slug}-{name}.png"));
        img.save(&path)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(dir.join(format!("{slug}-diff.png")))
}
