//! `index.html` (one self-contained page, no JavaScript, images beside it) and `README.md` (the
//! same tables in Markdown) from a [`Report`].

use std::fmt::Write;

use super::model::{Curve, Item, Report, Table};

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A number for people: 4 significant digits, scientific outside 1e-3..1e6.
pub fn num(v: f64) -> String {
    if v.is_nan() {
        return "NaN".into();
    }
    if v.is_infinite() {
        return if v > 0.0 { "inf" } else { "-inf" }.into();
    }
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if v.fract() == 0.0 && a < 1e6 {
        format!("{v:.0}")
    } else if !(1e-3..1e6).contains(&a) {
        format!("{v:.3e}")
    } else if a >= 1000.0 {
        format!("{v:.0}")
    } else if a >= 100.0 {
        format!("{v:.1}")
    } else if a >= 10.0 {
        format!("{v:.2}")
    } else if a >= 1.0 {
        format!("{v:.3}")
    } else {
        format!("{v:.4}")
    }
}

fn cell(v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::Number(n) => n.as_f64().map(num).unwrap_or_else(|| n.to_string()),
        serde_json::Value::String(s) => s.clone(),
        serde_json::Value::Null => "-".into(),
        other => other.to_string(),
    }
}

/// The rows of a curve's settings table: setting, x, y, extras, flags.
fn curve_rows(c: &Curve) -> (Vec<String>, Vec<Vec<String>>) {
    let mut head = vec!["setting".to_string(), c.x.label.clone(), c.y.label.clone()];
    let extras: Vec<String> = c
        .points
        .first()
        .map(|p| p.extra.iter().map(|(n, _)| n.clone()).collect())
        .unwrap_or_default();
    head.extend(extras.iter().cloned());
    head.push("".into());
    let rows = c
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let mut r = vec![p.label.clone(), num(p.x), num(p.y)];
            for name in &extras {
                let v = p.extra.iter().find(|(n, _)| n == name).map(|e| e.1);
                r.push(v.map(num).unwrap_or_else(|| "-".into()));
            }
            let mut flags = Vec::new();
            if p.default {
                flags.push("default");
            }
            if c.pareto.contains(&i) {
                flags.push("Pareto");
            }
            r.push(flags.join(", "));
            r
        })
        .collect();
    (head, rows)
}

fn html_table(out: &mut String, head: &[String], rows: &[Vec<String>]) {
    out.push_str("<table><thead><tr>");
    for h in head {
        let _ = write!(out, "<th>{}</th>", esc(h));
    }
    out.push_str("</tr></thead><tbody>\n");
    for r in rows {
        out.push_str("<tr>");
        for c in r {
            let _ = write!(out, "<td>{}</td>", esc(c));
        }
        out.push_str("</tr>\n");
    }
    out.push_str("</tbody></table>\n");
}

fn table_cells(t: &Table) -> Vec<Vec<String>> {
    t.rows
        .iter()
        .map(|r| r.iter().map(cell).collect())
        .collect()
}

const STYLE: &str =
    "body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:.5em 0 1.5em;font-size:13px}
td,th{border:1px solid #ccc;padding:3px 7px;text-align:right}
th{background:#f0f0f0}td:first-child,th:first-child{text-align:left}
figure{margin:1em 0}figcaption,.caption{font-size:14px;color:#444;max-width:900px}
.missing{background:#fff6d6;border:1px solid #e0c060;padding:.5em 1em;margin:1em 0}
.gallery{display:flex;flex-wrap:wrap;gap:10px}.gallery figure{margin:0}
.gallery img{max-width:340px;image-rendering:pixelated;border:1px solid #ddd}
.meta td{text-align:left}h2{border-bottom:2px solid #ddd;padding-top:1em}";

/// The page.
pub fn index_html(r: &Report) -> String {
    let mut o = String::new();
    o.push_str("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n");
    o.push_str("<title>vt report: speed and accuracy, measured</title>\n");
    let _ = writeln!(o, "<style>{STYLE}</style></head><body>");
    o.push_str("<h1>vt: what speed buys and what accuracy costs</h1>\n");
    o.push_str("<p>Every number on this page was measured by the run that wrote it (<code>cargo xtask report");
    if r.quick {
        o.push_str(" --quick");
    }
    o.push_str("</code>); nothing is pasted in. <code>report.json</code> beside this page holds every figure.</p>\n");
    o.push_str("<table class=\"meta\">");
    for (k, v) in [
        ("commit", r.commit.clone()),
        ("date (UTC)", r.date.clone()),
        (
            "machine",
            format!(
                "{}, {} cores, {:.1} GiB ({})",
                r.machine.cpu, r.machine.cores, r.machine.memory_gib, r.machine.os
            ),
        ),
        (
            "run",
            format!(
                "{}, {:.0} s, peak memory {:.0} MiB",
                if r.quick {
                    "--quick (smaller inputs)"
                } else {
                    "full"
                },
                r.seconds,
                r.peak_rss_mib
            ),
        ),
    ] {
        let _ = write!(o, "<tr><th>{}</th><td>{}</td></tr>", esc(k), esc(&v));
    }
    o.push_str("</table>\n<p>How to read the curves: each point is one setting of one knob, timed on this machine \
(x) and scored against truth (y). The orange line is the Pareto front: settings no other setting beats on both axes. \
The red triangle is vt's default. A knob whose default sits off the front is one to look at.</p>\n<ol>");
    for s in &r.sections {
        let _ = write!(o, "<li><a href=\"#{}\">{}</a></li>", s.id, esc(&s.title));
    }
    o.push_str("</ol>\n");
    for s in &r.sections {
        let _ = writeln!(
            o,
            "<h2 id=\"{}\">{}</h2>\n<p>{}</p>",
            s.id,
            esc(&s.title),
            esc(&s.intro)
        );
        for item in &s.items {
            match item {
                Item::Curve(c) => {
                    let _ = writeln!(
                        o,
                        "<h3 id=\"{}\">{}</h3><figure><img src=\"{}\" alt=\"{}\" width=\"720\" height=\"440\"><figcaption>{}</figcaption></figure>",
                        c.id,
                        esc(&c.title),
                        esc(&c.plot),
                        esc(&c.title),
                        esc(&c.caption)
                    );
                    let (h, rows) = curve_rows(c);
                    html_table(&mut o, &h, &rows);
                }
                Item::Plot(p) => {
                    let _ = writeln!(
                        o,
                        "<h3 id=\"{}\">{}</h3><figure><img src=\"{}\" alt=\"{}\" width=\"720\" height=\"440\"><figcaption>{}</figcaption></figure>",
                        p.id,
                        esc(&p.title),
                        esc(&p.plot),
                        esc(&p.title),
                        esc(&p.caption)
                    );
                }
                Item::Table(t) => {
                    let _ = writeln!(
                        o,
                        "<h3 id=\"{}\">{}</h3><p class=\"caption\">{}</p>",
                        t.id,
                        esc(&t.title),
                        esc(&t.caption)
                    );
                    html_table(&mut o, &t.columns, &table_cells(t));
                }
                Item::Gallery(g) => {
                    let _ = writeln!(
                        o,
                        "<h3>{}</h3><p class=\"caption\">{}</p><div class=\"gallery\">",
                        esc(&g.title),
                        esc(&g.caption)
                    );
                    for (file, cap) in &g.images {
                        let _ = writeln!(
                            o,
                            "<figure><img src=\"{}\" alt=\"{}\"><figcaption>{}</figcaption></figure>",
                            esc(file),
                            esc(cap),
                            esc(cap)
                        );
                    }
                    o.push_str("</div>\n");
                }
                Item::Missing { title, why } => {
                    let _ = writeln!(
                        o,
                        "<div class=\"missing\"><b>{}</b>: {}</div>",
                        esc(title),
                        esc(why)
                    );
                }
                Item::Note { text } => {
                    let _ = writeln!(o, "<p>{}</p>", esc(text));
                }
            }
        }
        let _ = writeln!(
            o,
            "<p class=\"caption\">(section measured in {:.1} s)</p>",
            s.seconds
        );
    }
    o.push_str("</body></html>\n");
    o
}

fn md_escape(s: &str) -> String {
    s.replace('|', "\\|").replace('\n', " ")
}

fn md_table(o: &mut String, head: &[String], rows: &[Vec<String>]) {
    let _ = writeln!(
        o,
        "| {} |",
        head.iter()
            .map(|h| md_escape(h))
            .collect::<Vec<_>>()
            .join(" | ")
    );
    let _ = writeln!(o, "|{}", " --- |".repeat(head.len()));
    for r in rows {
        let _ = writeln!(
            o,
            "| {} |",
            r.iter()
                .map(|c| md_escape(c))
                .collect::<Vec<_>>()
                .join(" | ")
        );
    }
    o.push('\n');
}

/// The tables in Markdown.
pub fn readme_md(r: &Report) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "# vt report\n\nMeasured by `cargo xtask report{}` at commit `{}` on {} ({}, {} cores, {:.1} GiB), {:.0} s. \
The plots are in `index.html`; every figure is in `report.json`.\n",
        if r.quick { " --quick" } else { "" },
        r.commit,
        r.date,
        r.machine.cpu,
        r.machine.cores,
        r.machine.memory_gib,
        r.seconds
    );
    for s in &r.sections {
        let _ = writeln!(o, "## {}\n\n{}\n", s.title, s.intro);
        for item in &s.items {
            match item {
                Item::Curve(c) => {
                    let _ = writeln!(o, "### {}\n\n{}\n", c.title, c.caption);
                    let (h, rows) = curve_rows(c);
                    md_table(&mut o, &h, &rows);
                }
                Item::Plot(p) => {
                    let _ = writeln!(o, "### {}\n\n{} (plot: `{}`)\n", p.title, p.caption, p.plot);
                }
                Item::Table(t) => {
                    let _ = writeln!(o, "### {}\n\n{}\n", t.title, t.caption);
                    md_table(&mut o, &t.columns, &table_cells(t));
                }
                Item::Gallery(g) => {
                    let _ = writeln!(o, "### {}\n\n{}\n", g.title, g.caption);
                    for (file, cap) in &g.images {
                        let _ = writeln!(o, "- `{file}`: {cap}");
                    }
                    o.push('\n');
                }
                Item::Missing { title, why } => {
                    let _ = writeln!(o, "**{title}**: {why}\n");
                }
                Item::Note { text } => {
                    let _ = writeln!(o, "{text}\n");
                }
            }
        }
    }
    o
}
