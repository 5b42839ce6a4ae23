//! The examples' settings, `key=value,...`, applied to the view's and the model's parameters.
//!
//! Texturing: `refs`, `smooth`, `sweep`, `step`, `window`, `fill`, `tol`, `soft`, `agree`,
//! `reach`, `consensus`, `within`, `eps`; the model: `pthr` (photo threshold), and the stereo
//! carving's `sources`, `best`, `radius`, `stride`, `step_v` (depth step in voxels), `coarse`,
//! `pixel`, `min_ncc`, `agree_v`, `margin`, `protect`, `passes`, `stereo` (0: off); the clip:
//! `grow`, `slack`, `close`.

use vt_fv::dataset::ModelParams;
use vt_fv::pipeline::ViewParams;

/// Applies `kv` (`key=value` pairs separated by commas); panics naming an unknown key.
pub fn apply(kv: &str, view: &mut ViewParams, model: &mut ModelParams) {
    for pair in kv.split(',').filter(|p| !p.is_empty()) {
        let (k, v) = pair.split_once('=').expect("key=value");
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
            "pthr" => model.photo_threshold = f(),
            "sources" => model.stereo_params.sources = f() as usize,
            "best" => model.stereo_params.best = f() as usize,
            "radius" => model.stereo_params.radius = f() as i32,
            "stride" => model.stereo_params.stride = f() as i32,
            "step_v" => model.stereo_params.step = f(),
            "coarse" => model.stereo_params.coarse = f() as usize,
            "pixel" => model.stereo_params.pixel_step = f() as usize,
            "min_ncc" => model.stereo_params.min_ncc = f(),
            "agree_v" => model.stereo_params.agree = f(),
            "margin" => model.stereo_params.margin = f(),
            "protect" => model.stereo_params.protect = f(),
            "passes" => model.stereo_params.passes = f() as usize,
            "stereo" => model.stereo = f() > 0.0,
            "grow" => view.grow = f() as u32,
            "slack" => view.clip.as_mut().expect("clip").slack = f() as u32,
            "close" => view.clip.as_mut().expect("clip").close = f() as u32,
            _ => panic!("unknown key {k}"),
        }
    }
}
