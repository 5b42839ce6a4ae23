//! The examples' settings, `key=value,...`, applied to the view's and the model's parameters.
//!
//! Texturing: `refs`, `smooth`, `sweep`, `step`, `window`, `fill`, `tol`, `soft`, `agree`,
//! `reach`, `consensus`, `within`, `eps`, `snap`; the model: `pthr` (photo threshold), and the stereo
//! carving's `sources`, `best`, `radius`, `stride`, `step_v` (depth step in voxels), `coarse`,
//! `pixel`, `min_ncc`, `agree_v`, `margin`, `protect`, `passes`, `pm` (PatchMatch iterations,
//! 0: the sweep), `geo` (geometric round's iterations), `geow` (its weight), `conf`
//! (confirmations), `unseen` (-1: off), `texture`, `colour`, `fine` (iterations at every
//! pixel), `holefill` (0: off), `grid`, `stereo` (0: off); the clip:
//! `grow`, `slack`, `close`, `exact` (0: never raw silhouettes), `before`, `behind`; the depth clip: `dclip` (0: off), `dmargin`, `dprotect`,
//! `dthrough`.

// Each example includes this file and uses part of it.
#![allow(dead_code)]

use vt_fv::dataset::ModelParams;
use vt_fv::pipeline::ViewParams;

/// Applies `kv` (`key=value` pairs separated by commas); panics naming an unknown key.
pub fn apply(kv: &str, view: &mut ViewParams, model: &mut ModelParams) {
    for pair in kv.split(',').filter(|p| !p.is_empty()) {
        let (k, v) = pair.split_once('=').expect("key=value");
        if !apply_view(k, v, view) && !apply_model(k, v, model) {
            panic!("unknown key {k}");
        }
    }
}

/// One texturing or clip key; false when `k` is not one.
pub fn apply_view(k: &str, v: &str, view: &mut ViewParams) -> bool {
    let f = || v.parse::<f64>().unwrap();
    let t = &mut view.texture;
    match k {
        "refs" => t.references = f() as usize,
        "smooth" => t.depth_smooth = f() as u32,
        "sweep" => t.sweep = f() as usize,
        "step" => t.sweep_step = f(),
        "window" => t.sweep_window = f() as u32,
        "fill" => t.fill_radius = f() as u32,
        "tol" => t.depth_tolerance = f(),
        "soft" => t.soften_sigma = f(),
        "agree" => t.agree_sd = f(),
        "reach" => t.reach_deg = f(),
        "consensus" => t.consensus = f(),
        "within" => t.soften_within = f() > 0.0,
        "eps" => t.eps_deg = f(),
        "snap" => t.snap = f(),
        "grow" => view.grow = f() as u32,
        "dclip" => view.depth_clip = (f() > 0.0).then(Default::default),
        "dmargin" => view.depth_clip.as_mut().expect("dclip").margin = f(),
        "dthrough" => view.depth_clip.as_mut().expect("dclip").through = f() as usize,
        "dprotect" => view.depth_clip.as_mut().expect("dclip").protect = f(),
        "slack" => view.clip.as_mut().expect("clip").slack = f() as u32,
        "close" => view.clip.as_mut().expect("clip").close = f() as u32,
        "exact" => view.clip.as_mut().expect("clip").exact = f() > 0.0,
        "before" => view.clip.as_mut().expect("clip").before = f(),
        "behind" => view.clip.as_mut().expect("clip").behind = f(),
        _ => return false,
    }
    true
}

/// One model key; false when `k` is not one.
fn apply_model(k: &str, v: &str, model: &mut ModelParams) -> bool {
    let f = || v.parse::<f64>().unwrap();
    let st = &mut model.stereo_params;
    match k {
        "pthr" => model.photo_threshold = f(),
        "sources" => st.sources = f() as usize,
        "best" => st.best = f() as usize,
        "radius" => st.radius = f() as i32,
        "stride" => st.stride = f() as i32,
        "step_v" => st.step = f(),
        "coarse" => st.coarse = f() as usize,
        "pixel" => st.pixel_step = f() as usize,
        "min_ncc" => st.min_ncc = f(),
        "agree_v" => st.agree = f(),
        "margin" => st.margin = f(),
        "protect" => st.protect = f(),
        "passes" => st.passes = f() as usize,
        "pm" => st.patchmatch = f() as usize,
        "geo" => st.geo_iters = f() as usize,
        "geow" => st.geo_weight = f(),
        "conf" => st.confirmations = f() as usize,
        "unseen" => st.unseen_keep = (f() >= 0.0).then(|| f() as usize),
        "texture" => st.min_texture = f(),
        "colour" => st.colour = f() > 0.0,
        "fine" => st.fine = f() as usize,
        "holefill" => st.hole_fill = f() as usize,
        "grid" => model.grid = f() as usize,
        "stereo" => model.stereo = f() > 0.0,
        _ => return false,
    }
    true
}
