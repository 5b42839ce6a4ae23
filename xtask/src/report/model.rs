//! What the report holds: sections of curves, tables, images and notes, serialised as they are
//! into `report.json` and drawn into `index.html` and `README.md`.

use serde::Serialize;

/// Which way an axis improves (for the Pareto front).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Better {
    /// Smaller values are better (time, error).
    Lower,
    /// Larger values are better (PSNR, recall).
    Higher,
    /// Neither (a sweep's input).
    Neutral,
}

/// One axis of a curve.
#[derive(Debug, Clone, Serialize)]
pub struct Axis {
    /// Label with its unit.
    pub label: String,
    /// Direction of improvement.
    pub better: Better,
    /// Draw on a log scale.
    pub log: bool,
}

impl Axis {
    /// A linear axis.
    pub fn new(label: &str, better: Better) -> Self {
        Self {
            label: label.into(),
            better,
            log: false,
        }
    }

    /// A log-scale axis.
    pub fn log(label: &str, better: Better) -> Self {
        Self {
            label: label.into(),
            better,
            log: true,
        }
    }
}

/// One setting of a knob, measured.
#[derive(Debug, Clone, Serialize)]
pub struct Setting {
    /// The setting, as the user would write it (`ksize 5`).
    pub label: String,
    /// Value on the x axis.
    pub x: f64,
    /// Value on the y axis.
    pub y: f64,
    /// Is this the default?
    pub default: bool,
    /// Further figures of the same run (shown in the table under the plot).
    pub extra: Vec<(String, f64)>,
}

impl Setting {
    /// A setting without extra figures.
    pub fn new(label: impl Into<String>, x: f64, y: f64, default: bool) -> Self {
        Self {
            label: label.into(),
            x,
            y,
            default,
            extra: Vec::new(),
        }
    }

    /// Adds an extra figure.
    pub fn with(mut self, name: &str, value: f64) -> Self {
        self.extra.push((name.into(), value));
        self
    }
}

/// A knob's speed/accuracy curve: every setting a point, the Pareto front, the default marked.
#[derive(Debug, Clone, Serialize)]
pub struct Curve {
    /// Stable id (file names, JSON).
    pub id: String,
    /// Title (the knob).
    pub title: String,
    /// What was measured, on what input, and how to read it.
    pub caption: String,
    /// Horizontal axis.
    pub x: Axis,
    /// Vertical axis.
    pub y: Axis,
    /// The measured settings.
    pub points: Vec<Setting>,
    /// Indices into `points` of the Pareto-optimal settings, in x order.
    pub pareto: Vec<usize>,
    /// The plot file, relative to the report directory.
    pub plot: String,
}

impl Curve {
    /// A curve with its Pareto front computed (finite points only).
    pub fn new(
        id: &str,
        title: &str,
        caption: String,
        x: Axis,
        y: Axis,
        points: Vec<Setting>,
    ) -> Self {
        let pareto = pareto_front(&points, x.better, y.better);
        Self {
            id: id.into(),
            title: title.into(),
            caption,
            x,
            y,
            points,
            pareto,
            plot: format!("plots/{id}.svg"),
        }
    }
}

/// Indices of the points no other point beats on both axes (ties kept), sorted by x.
pub fn pareto_front(points: &[Setting], bx: Better, by: Better) -> Vec<usize> {
    let key = |v: f64, b: Better| if b == Better::Higher { -v } else { v };
    let finite: Vec<usize> = (0..points.len())
        .filter(|&i| points[i].x.is_finite() && points[i].y.is_finite())
        .collect();
    let mut front: Vec<usize> = finite
        .iter()
        .copied()
        .filter(|&i| {
            let (xi, yi) = (key(points[i].x, bx), key(points[i].y, by));
            !finite.iter().any(|&j| {
                let (xj, yj) = (key(points[j].x, bx), key(points[j].y, by));
                xj <= xi && yj <= yi && (xj < xi || yj < yi)
            })
        })
        .collect();
    front.sort_by(|&a, &b| points[a].x.total_cmp(&points[b].x));
    front
}

/// A series of a line plot (not a knob: e.g. PSNR of each model along a sweep).
#[derive(Debug, Clone, Serialize)]
pub struct Series {
    /// Legend.
    pub name: String,
    /// (x, y) points.
    pub points: Vec<(f64, f64)>,
}

/// A plot of several series against one x.
#[derive(Debug, Clone, Serialize)]
pub struct LinePlot {
    /// Stable id.
    pub id: String,
    /// Title.
    pub title: String,
    /// What was measured and how to read it.
    pub caption: String,
    /// Horizontal axis.
    pub x: Axis,
    /// Vertical axis.
    pub y: Axis,
    /// The series.
    pub series: Vec<Series>,
    /// Plot file, relative to the report directory.
    pub plot: String,
}

/// A table: a header and rows of cells (numbers stay numbers in JSON).
#[derive(Debug, Clone, Serialize)]
pub struct Table {
    /// Stable id.
    pub id: String,
    /// Title.
    pub title: String,
    /// What the rows are and how to read them.
    pub caption: String,
    /// Column names.
    pub columns: Vec<String>,
    /// Rows.
    pub rows: Vec<Vec<serde_json::Value>>,
}

impl Table {
    /// An empty table with these columns.
    pub fn new(id: &str, title: &str, caption: impl Into<String>, columns: &[&str]) -> Self {
        Self {
            id: id.into(),
            title: title.into(),
            caption: caption.into(),
            columns: columns.iter().map(|c| c.to_string()).collect(),
            rows: Vec::new(),
        }
    }

    /// Appends a row.
    pub fn row(&mut self, cells: Vec<serde_json::Value>) {
        self.rows.push(cells);
    }
}

/// Images side by side, each with its own caption.
#[derive(Debug, Clone, Serialize)]
pub struct Gallery {
    /// Title.
    pub title: String,
    /// What the images are.
    pub caption: String,
    /// (file relative to the report directory, caption).
    pub images: Vec<(String, String)>,
}

/// One thing on the page.
#[derive(Debug, Clone, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Item {
    /// A knob's curve.
    Curve(Curve),
    /// A multi-series plot.
    Plot(LinePlot),
    /// A table.
    Table(Table),
    /// Images.
    Gallery(Gallery),
    /// A knob or measurement that does not exist yet, said plainly.
    Missing {
        /// What would be measured.
        title: String,
        /// Why it is not.
        why: String,
    },
    /// A paragraph.
    Note {
        /// The text.
        text: String,
    },
}

/// A section of the page.
#[derive(Debug, Clone, Serialize)]
pub struct Section {
    /// Anchor id.
    pub id: String,
    /// Heading.
    pub title: String,
    /// Opening paragraph.
    pub intro: String,
    /// Content.
    pub items: Vec<Item>,
    /// Seconds this section took to measure.
    pub seconds: f64,
}

/// Where the figures were measured.
#[derive(Debug, Clone, Serialize)]
pub struct Machine {
    /// CPU model name.
    pub cpu: String,
    /// Logical cores available to this process.
    pub cores: usize,
    /// Total memory, GiB.
    pub memory_gib: f64,
    /// Operating system line.
    pub os: String,
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// Format tag.
    pub format: String,
    /// `--quick` run?
    pub quick: bool,
    /// Git commit (with `-dirty` when the tree had changes).
    pub commit: String,
    /// UTC date and time of the run.
    pub date: String,
    /// The machine.
    pub machine: Machine,
    /// Total seconds.
    pub seconds: f64,
    /// Peak resident memory of the report process, MiB.
    pub peak_rss_mib: f64,
    /// The sections.
    pub sections: Vec<Section>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pts(v: &[(f64, f64)]) -> Vec<Setting> {
        v.iter()
            .enumerate()
            .map(|(i, &(x, y))| Setting::new(format!("{i}"), x, y, false))
            .collect()
    }

    #[test]
    fn pareto_front_keeps_exactly_the_undominated_points() {
        // Lower is better on both: (1, 5), (2, 3), (4, 1) trade; (3, 4) is beaten by (2, 3);
        // (2, 3) twice are both kept; NaN is never on the front.
        let p = pts(&[
            (3.0, 4.0),
            (4.0, 1.0),
            (1.0, 5.0),
            (2.0, 3.0),
            (f64::NAN, 0.0),
            (2.0, 3.0),
        ]);
        assert_eq!(
            pareto_front(&p, Better::Lower, Better::Lower),
            vec![2, 3, 5, 1]
        );
        // Higher y is better: (4, 1) is now the worst y; (1, 5) beats everything.
        assert_eq!(pareto_front(&p, Better::Lower, Better::Higher), vec![2]);
    }
}
