//! `cargo xtask report`: the page is complete and every image on it loads.
//!
//! The ignored test (run with `-- --ignored`, as `scripts/test-all` does; a plain `cargo test`
//! lists it as ignored) runs the real `cargo xtask report --quick` into a temporary directory
//! (minutes) and checks the page, the JSON and the Markdown; headless Chromium then opens the
//! page and counts broken images. The other test checks the Chromium checker itself, on a page
//! with one good and one missing image.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

/// Attribute values `name="..."` in `html`.
fn attributes(html: &str, name: &str) -> Vec<String> {
    let pat = format!("{name}=\"");
    html.match_indices(&pat)
        .filter_map(|(i, _)| {
            let rest = &html[i + pat.len()..];
            rest.find('"').map(|j| rest[..j].to_string())
        })
        .collect()
}

/// Opens `page` in headless Chromium and returns (images loaded, images broken, names of the
/// broken ones). A copy of the page with a small script beside it does the counting after the
/// load event; the page itself has no script.
fn chromium_image_check(page: &Path) -> (usize, usize, String) {
    let html = std::fs::read_to_string(page).unwrap();
    let script = r#"<pre id="img-check">pending</pre><script>
window.addEventListener('load', function () {
  var ok = 0, bad = [];
  for (var i = 0; i < document.images.length; i++) {
    var im = document.images[i];
    if (im.complete && im.naturalWidth > 0) { ok++; } else { bad.push(im.getAttribute('src')); }
  }
  document.getElementById('img-check').textContent = 'ok=' + ok + ' broken=' + bad.length + ' [' + bad.join(' ') + ']';
});
</script>"#;
    let checked = html.replace("</body>", &format!("{script}</body>"));
    let copy = page.with_file_name("chromium-image-check.html");
    std::fs::write(&copy, checked).unwrap();
    let profile = tempfile::tempdir().unwrap();
    let out = Command::new("chromium")
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--allow-file-access-from-files",
            "--virtual-time-budget=20000",
            "--dump-dom",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg(format!("file://{}", copy.display()))
        .output()
        .expect("chromium is installed by scripts/test-all (apt-get install chromium)");
    std::fs::remove_file(&copy).ok();
    let dom = String::from_utf8_lossy(&out.stdout);
    let marker = "<pre id=\"img-check\">";
    let at = dom.find(marker).unwrap_or_else(|| {
        panic!(
            "chromium printed no image check; stderr: {}",
            String::from_utf8_lossy(&out.stderr)
        )
    });
    let text = &dom[at + marker.len()..];
    let text = &text[..text.find("</pre>").unwrap()];
    assert!(text.starts_with("ok="), "the check did not run: {text:?}");
    let num = |key: &str| -> usize {
        let s = &text[text.find(key).unwrap() + key.len()..];
        s.split(|c: char| !c.is_ascii_digit())
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    let list = text[text.find('[').unwrap()..].to_string();
    (num("ok="), num("broken="), list)
}

#[test]
fn chromium_check_finds_a_broken_image() {
    let dir = tempfile::tempdir().unwrap();
    image::RgbImage::from_pixel(4, 3, image::Rgb([200, 10, 10]))
        .save(dir.path().join("good.png"))
        .unwrap();
    std::fs::write(
        dir.path().join("svg.svg"),
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"20\" height=\"10\"><text x=\"1\" y=\"9\">a</text></svg>",
    )
    .unwrap();
    let page = dir.path().join("index.html");
    std::fs::write(
        &page,
        "<!DOCTYPE html><html><body><img src=\"good.png\"><img src=\"svg.svg\"><img src=\"missing.png\"></body></html>",
    )
    .unwrap();
    let (ok, broken, list) = chromium_image_check(&page);
    assert_eq!((ok, broken), (2, 1), "{list}");
    assert!(list.contains("missing.png"), "{list}");
}

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

fn section<'a>(report: &'a Value, id: &str) -> &'a Vec<Value> {
    report["sections"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["id"] == id)
        .unwrap_or_else(|| panic!("no section {id}"))["items"]
        .as_array()
        .unwrap()
}

fn items<'a>(report: &'a Value, id: &str, kind: &str) -> Vec<&'a Value> {
    section(report, id)
        .iter()
        .filter(|i| i["kind"] == kind)
        .collect()
}

#[test]
#[ignore = "minutes: runs cargo xtask report --quick; run: cargo test -p xtask --test report -- --ignored"]
fn quick_report_is_complete_and_every_image_loads() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("report");
    // xtask as built with this test: optimised (the test command's `checked` profile, or
    // release) it measures in-process; otherwise it re-runs itself in release.
    let status = Command::new(env!("CARGO_BIN_EXE_xtask"))
        .current_dir(workspace())
        .args(["report", "--quick", "--out"])
        .arg(&out)
        .status()
        .unwrap();
    assert!(
        status.success(),
        "cargo xtask report --quick failed: {status}"
    );

    // The page references only files that exist, nothing on the network, and runs no script.
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(
        !html.contains("<script"),
        "the page must read without JavaScript"
    );
    let refs: Vec<String> = attributes(&html, "src")
        .into_iter()
        .chain(
            attributes(&html, "href")
                .into_iter()
                .filter(|h| !h.starts_with('#')),
        )
        .collect();
    assert!(
        refs.len() >= 20,
        "only {} images/links on the page",
        refs.len()
    );
    for r in &refs {
        assert!(!r.contains("://"), "{r}: the page must need no network");
        assert!(
            out.join(r).is_file(),
            "index.html references {r}, which does not exist"
        );
    }

    // report.json: machine, commit, date; section 1's curves; sections 2-4's tables.
    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["format"], "vt-report 1");
    assert!(!report["commit"].as_str().unwrap().is_empty());
    assert!(!report["date"].as_str().unwrap().is_empty());
    assert!(!report["machine"]["cpu"].as_str().unwrap().is_empty());
    assert!(report["machine"]["cores"].as_u64().unwrap() >= 1);
    assert!(report["machine"]["memory_gib"].as_f64().unwrap() > 0.0);
    let curves = items(&report, "curves", "curve");
    let ids: Vec<&str> = curves.iter().map(|c| c["id"].as_str().unwrap()).collect();
    for want in [
        "a-median",
        "a-blur",
        "a-threshold",
        "a-window",
        "a-mask-resolution",
        "a-render",
        "a-crossfade",
        "a-refine",
        "a-appearance",
        "a-noise",
        "b-grid",
        "b-photo-threshold-psnr",
        "b-photo-threshold-iou",
        "b-patch",
        "b-step",
        "b-levels",
        "b-iterations",
        "b-references",
    ] {
        assert!(
            ids.contains(&want),
            "section 1 lacks the curve {want} (has {ids:?})"
        );
    }
    for c in &curves {
        let id = c["id"].as_str().unwrap();
        let points = c["points"].as_array().unwrap();
        assert!(points.len() >= 3, "{id}: {} points", points.len());
        let front = c["pareto"].as_array().unwrap();
        assert!(!front.is_empty(), "{id}: empty Pareto front");
        for i in front {
            let p = &points[i.as_u64().unwrap() as usize];
            assert!(
                p["x"].is_number() && p["y"].is_number(),
                "{id}: front point {p}"
            );
        }
        assert!(
            out.join(c["plot"].as_str().unwrap()).is_file(),
            "{id}: no plot"
        );
    }
    let md = std::fs::read_to_string(out.join("README.md")).unwrap();
    for (sec, want) in [
        (
            "stability",
            &[
                "stability-homography",
                "stability-images",
                "stability-render",
            ][..],
        ),
        (
            "models",
            &["models-scenes", "models-sweep-truth", "models-sweep-noise"][..],
        ),
        (
            "real",
            &["real-a-transitions", "real-a-corners", "real-b-temple"][..],
        ),
    ] {
        let tables = items(&report, sec, "table");
        for id in want {
            let t = tables
                .iter()
                .find(|t| t["id"] == *id)
                .unwrap_or_else(|| panic!("section {sec} lacks the table {id}"));
            let cols = t["columns"].as_array().unwrap().len();
            let rows = t["rows"].as_array().unwrap();
            assert!(!rows.is_empty(), "{id}: no rows");
            for r in rows {
                assert_eq!(r.as_array().unwrap().len(), cols, "{id}: row {r}");
            }
            assert!(
                md.contains(t["title"].as_str().unwrap()),
                "README.md lacks {id}"
            );
        }
    }
    assert!(
        !items(&report, "gallery", "gallery").is_empty()
            && !items(&report, "performance", "table").is_empty(),
        "gallery and performance sections are empty"
    );

    // Every image on the page loads in a real browser.
    let n_img = html.matches("<img ").count();
    let (ok, broken, list) = chromium_image_check(&out.join("index.html"));
    assert_eq!(broken, 0, "broken images: {list}");
    assert_eq!(ok, n_img, "{ok} of {n_img} images loaded");
}
