//! Fuzzing the Middlebury par-file parser on stable Rust with proptest: random text and
//! structure-aware mutations of templeSparseRing's real par file (testdata/). No input may
//! panic; an accepted file has as many cameras as it declares, each with a rotation R and an
//! image name inside the data folder.
//!
//! 10,000 cases in the test command; `VT_FUZZ_CASES=1000000 cargo test --release -p vt-fv --test
//! fuzz_par` is the long run (its last result is in crates/vt-io/README.md, with vt-io's).

use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use vt_fv::camera::parse_par;

const PAR: &str = include_str!("../../../testdata/templeSparseRing/templeSR_par.txt");

fn cases() -> u32 {
    std::env::var("VT_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000)
}

/// Tokens to put anywhere: numbers good and bad, names inside and outside the folder.
fn token() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<f64>().prop_map(|x| x.to_string()),
        (-2.0f64..2.0).prop_map(|x| x.to_string()),
        any::<u64>().prop_map(|x| x.to_string()),
        Just("1e12".to_string()),
        Just("1000000000000".to_string()),
        Just("nan".to_string()),
        Just("-inf".to_string()),
        Just("../../x.png".to_string()),
        Just("/etc/passwd".to_string()),
        Just(String::new()),
        "[ -~]{0,10}",
    ]
}

/// An edit of the real file, line and field aware.
#[derive(Debug, Clone)]
enum Edit {
    Field(usize, usize, String),
    DropLine(usize),
    DupLine(usize),
    DropField(usize, usize),
    Header(String),
    Truncate(usize),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (any::<usize>(), any::<usize>(), token()).prop_map(|(l, f, t)| Edit::Field(l, f, t)),
        any::<usize>().prop_map(Edit::DropLine),
        any::<usize>().prop_map(Edit::DupLine),
        (any::<usize>(), any::<usize>()).prop_map(|(l, f)| Edit::DropField(l, f)),
        token().prop_map(Edit::Header),
        any::<usize>().prop_map(Edit::Truncate),
    ]
}

fn apply(text: &str, edits: &[Edit]) -> String {
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    for e in edits {
        let n = lines.len().max(1);
        match e {
            Edit::Field(l, f, t) => {
                if let Some(line) = lines.get_mut(l % n) {
                    let mut fs: Vec<String> = line.split_whitespace().map(String::from).collect();
                    if !fs.is_empty() {
                        let k = f % fs.len();
                        fs[k] = t.clone();
                    }
                    *line = fs.join(" ");
                }
            }
            Edit::DropLine(l) => {
                if !lines.is_empty() {
                    lines.remove(l % n);
                }
            }
            Edit::DupLine(l) => {
                if let Some(line) = lines.get(l % n).cloned() {
                    lines.insert(l % n, line);
                }
            }
            Edit::DropField(l, f) => {
                if let Some(line) = lines.get_mut(l % n) {
                    let mut fs: Vec<&str> = line.split_whitespace().collect();
                    if !fs.is_empty() {
                        fs.remove(f % fs.len());
                    }
                    *line = fs.join(" ");
                }
            }
            Edit::Header(t) => {
                if let Some(h) = lines.first_mut() {
                    *h = t.clone();
                }
            }
            Edit::Truncate(k) => {
                let all = lines.join("\n");
                let cut = k % (all.len() + 1);
                let cut = (0..=cut)
                    .rev()
                    .find(|&i| all.is_char_boundary(i))
                    .unwrap_or(0);
                lines = all[..cut].lines().map(String::from).collect();
            }
        }
    }
    lines.join("\n")
}

#[test]
fn fuzz_par_file() {
    let real = parse_par(PAR).expect("the real par file parses");
    assert_eq!(real.len(), 16);
    let strategy = prop_oneof![
        4 => prop::collection::vec(edit(), 1..5).prop_map(|e| apply(PAR, &e)),
        1 => prop::collection::vec(any::<u8>(), 0..300)
            .prop_map(|b| String::from_utf8_lossy(&b).to_string()),
        1 => prop::collection::vec(token(), 0..30).prop_map(|t| t.join(" ")),
    ];
    let mut runner = TestRunner::new(Config {
        cases: cases(),
        failure_persistence: None,
        ..Config::default()
    });
    runner
        .run(&strategy, |text| {
            if let Ok(cams) = parse_par(&text) {
                let declared: usize = text
                    .lines()
                    .find(|l| !l.trim().is_empty())
                    .and_then(|l| l.trim().parse().ok())
                    .unwrap_or(usize::MAX);
                prop_assert_eq!(cams.len(), declared);
                for c in &cams {
                    let inside = std::path::Path::new(&c.name).components().all(|k| {
                        matches!(
                            k,
                            std::path::Component::Normal(_) | std::path::Component::CurDir
                        )
                    });
                    prop_assert!(inside, "{:?} accepted", c.name);
                    let r = c.r;
                    prop_assert!((r.determinant() - 1.0).abs() < 1e-2);
                }
            }
            Ok(())
        })
        .unwrap();
}
