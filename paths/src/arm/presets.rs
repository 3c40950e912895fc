//! Looking up a built-in arm by model name, for every kind's table of presets.

use crate::Error;

/// The preset whose model (`model_of`) is `model`, case-insensitive.
pub(crate) fn find<'a, T>(
    presets: &'a [T],
    model_of: fn(&T) -> &str,
    model: &str,
) -> Option<&'a T> {
    presets
        .iter()
        .find(|p| model_of(p).eq_ignore_ascii_case(model))
}

/// The preset of that model, or [`Error::UnknownArmModel`] naming `kind` and the known models.
pub(crate) fn named<'a, T>(
    presets: &'a [T],
    model_of: fn(&T) -> &str,
    kind: &'static str,
    model: &str,
) -> Result<&'a T, Error> {
    find(presets, model_of, model).ok_or_else(|| Error::UnknownArmModel {
        kind,
        model: model.to_string(),
        known: names(presets, model_of),
    })
}

/// The known model names, quoted and comma-separated, for messages.
pub(crate) fn names<T>(presets: &[T], model_of: fn(&T) -> &str) -> String {
    presets
        .iter()
        .map(|p| format!("\"{}\"", model_of(p)))
        .collect::<Vec<_>>()
        .join(", ")
}
