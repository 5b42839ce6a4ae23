//! The libraries' errors in the user's words: a parameter named by the flag that sets it.

use anyhow::anyhow;

/// The flag that sets a parameter, by the libraries' name of it (vt-core's `InvalidParameter`,
/// vt-app's `Param`, vt-web's and vt-view's parameter errors).
pub fn flag_of(name: &str) -> Option<&'static str> {
    Some(match name {
        "blur.ksize" => "--blur-size",
        "blur.sigma" => "--blur-sigma",
        "loops.window" => "--window",
        "loops.min_length" => "--min-length",
        "mask.open_radius" => "--open",
        "mask.close_radius" => "--close",
        "alternative_loops" => "--alternatives",
        "model.sigma" => "--point-sigma",
        "appearance" => "--appearance",
        "median_frames" => "--median-frames",
        "noise.k" => "--noise-k",
        "fps" => "--fps",
        "crossfade" => "--crossfade",
        "dissolve" => "--dissolve",
        "crf" => "--crf",
        "quality" => "--quality",
        "port" => "--port",
        "q" => "--q",
        "frames" => "--frames",
        "out" => "--out",
        "save" => "--save",
        "model" => "--model",
        "masks" => "--masks",
        "camera" => "--camera",
        "method" => "--method",
        "regions.tile" => "--region-tile",
        "regions.spatial" => "--region-spatial",
        "regions.feather" => "--region-feather",
        "regions.blend" => "--region-blend",
        "regions.spread" => "--region-spread",
        _ => return None,
    })
}

/// `flag value: why` (`flag: why` without a value); a name with no flag in the table is
/// vt-fv's, whose flags are its names with dashes.
fn param(name: &str, value: &str, why: &str) -> anyhow::Error {
    let flag = flag_of(name)
        .map(str::to_string)
        .unwrap_or_else(|| format!("--{}", name.replace('_', "-")));
    if value.is_empty() {
        anyhow!("{flag}: {why}")
    } else {
        anyhow!("{flag} {value}: {why}")
    }
}

/// A vt-app error as one line in the flags' words.
pub fn flagged(e: vt_app::Error) -> anyhow::Error {
    use vt_app::Error as E;
    match e {
        E::Core(vt_core::Error::InvalidParameter { name, value, why }) => param(name, &value, &why),
        E::Param { name, value, why } => param(name, &value, &why),
        E::Web(vt_web::Error::InvalidParameter { name, value, why }) => param(name, &value, &why),
        E::View(vt_view::Error::Param { name, value, why }) => param(name, &value, &why),
        E::Fv(vt_fv::Error::BadParam { name, value, why }) => param(&name, &value, &why),
        E::Field { name, cause } => {
            let flag = flag_of(name).unwrap_or(name);
            anyhow!("{flag} {}", crate::error_line(&flagged(*cause)))
        }
        E::In { what, cause } => anyhow!("{what}: {}", crate::error_line(&flagged(*cause))),
        E::View(vt_view::Error::Listen { port, cause }) => {
            anyhow!("--port {port}: cannot listen on 127.0.0.1: {cause}")
        }
        // The way out, in the flag's words: a shorter minimum loop.
        E::TooShort {
            cause,
            max_min_length,
        } => anyhow!("{cause}; for a clip this short pass --min-length {max_min_length} or less"),
        e => e.into(),
    }
}
