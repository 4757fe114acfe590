//! MTL numbers checked with file and line before tobj reads the library (tobj reports no
//! lines): reflectances and emission must be finite and non-negative; a diffuse reflectance
//! above 1 is clamped to 1 by the renderer, with a warning here.

use std::path::Path;

use crate::error::{Error, Result};

/// Checks the colour and scalar statements of an MTL file's text (read from `path`).
pub(crate) fn check(path: &Path, text: &str) -> Result<()> {
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        if !matches!(key, "Kd" | "Ka" | "Ks" | "Ke" | "Ni" | "Ns" | "d" | "Tr") {
            continue;
        }
        let tokens: Vec<&str> = words.collect();
        let bad = |msg: String| Error::input(path, Some(i + 1), msg);
        // tobj reads the first three tokens of a colour and panics on fewer.
        if matches!(key, "Kd" | "Ka" | "Ks" | "Ke") && tokens.len() < 3 {
            return Err(bad(format!(
                "{key} needs three numbers (r g b), found {}",
                tokens.len()
            )));
        }
        // Only tokens that read as numbers; tobj refuses other forms ("Kd spectral …").
        let values: Vec<f32> = tokens.iter().filter_map(|w| w.parse().ok()).collect();
        if let Some(x) = values.iter().find(|x| !x.is_finite()) {
            return Err(bad(format!("{key} {x}: values must be finite numbers")));
        }
        if let Some(x) = values.iter().find(|&&x| x < 0.0) {
            return Err(bad(format!("{key} {x}: values must not be negative")));
        }
        if key == "Kd" && values.iter().any(|&x| x > 1.0) {
            log::warn!(
                "{}:{}: Kd {values:?} reflects more light than arrives; clamped to 1",
                path.display(),
                i + 1
            );
        }
    }
    Ok(())
}
