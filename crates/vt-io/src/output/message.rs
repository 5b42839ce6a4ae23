//! User-supplied values shortened for one-line messages.

/// Shortens a user-supplied value for a message: at most 40 characters, the rest counted.
pub fn shorten(s: &str) -> String {
    const MAX: usize = 40;
    let n = s.chars().count();
    if n <= MAX {
        return s.to_string();
    }
    let head: String = s.chars().take(MAX - 8).collect();
    format!("{head}... ({n} characters)")
}

/// Formats a user-supplied number for a message: as Rust prints it when that is short, else in
/// scientific notation (`1e-300`, not 300 digits).
pub fn num(x: f64) -> String {
    let plain = x.to_string();
    if plain.len() <= 24 {
        plain
    } else {
        format!("{x:e}")
    }
}
