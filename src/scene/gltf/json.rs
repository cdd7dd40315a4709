//! Lenient, type-checked access to the glTF JSON tree (`serde_json::Value`).
//!
//! The loader reads the JSON itself instead of deserialising it into `gltf::json::Root`,
//! because that schema rejects valid files at the serde level (a scene without `nodes`, an
//! integer written as `1.0`, an animation channel without `node`, a texture without
//! `source`, an unknown light type) and the crate panics on some invalid ones. Every getter
//! here returns `Err(message)` for a value of the wrong type and `Ok(None)` when absent, so
//! callers decide whether a problem is fatal or a warning.

use serde_json::Value;

/// Short human-readable description of a JSON value, for error messages.
pub(super) fn describe(v: &Value) -> String {
    let s = v.to_string();
    if s.chars().count() > 40 {
        let cut: String = s.chars().take(37).collect();
        format!("{cut}...")
    } else {
        s
    }
}

/// An integral JSON number as `u64` (also accepting `2.0`, which the spec tolerates as an
/// integer written as float), or `None` for anything else.
pub(super) fn as_uint(v: &Value) -> Option<u64> {
    if let Some(u) = v.as_u64() {
        return Some(u);
    }
    let f = v.as_f64()?;
    (f >= 0.0 && f.fract() == 0.0 && f <= u64::MAX as f64).then_some(f as u64)
}

/// Optional non-negative integer property `key` (an index, count, offset or enum value).
pub(super) fn uint(obj: &Value, key: &str) -> Result<Option<u64>, String> {
    match obj.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(v) => as_uint(v).map(Some).ok_or_else(|| {
            format!(
                "`{key}` must be a non-negative integer, found {}",
                describe(v)
            )
        }),
    }
}

/// Optional index property `key`, as `usize`.
pub(super) fn index(obj: &Value, key: &str) -> Result<Option<usize>, String> {
    uint(obj, key).map(|o| o.map(|u| usize::try_from(u).unwrap_or(usize::MAX)))
}

/// Optional number property `key`.
pub(super) fn number(obj: &Value, key: &str) -> Result<Option<f64>, String> {
    match obj.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(v) => v
            .as_f64()
            .map(Some)
            .ok_or_else(|| format!("`{key}` must be a number, found {}", describe(v))),
    }
}

/// Optional boolean property `key`.
pub(super) fn boolean(obj: &Value, key: &str) -> Result<Option<bool>, String> {
    match obj.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(v) => v
            .as_bool()
            .map(Some)
            .ok_or_else(|| format!("`{key}` must be true or false, found {}", describe(v))),
    }
}

/// Optional string property `key`.
pub(super) fn string<'a>(obj: &'a Value, key: &str) -> Result<Option<&'a str>, String> {
    match obj.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(v) => v
            .as_str()
            .map(Some)
            .ok_or_else(|| format!("`{key}` must be a string, found {}", describe(v))),
    }
}

/// Optional array property `key` (absent gives an empty slice).
pub(super) fn array<'a>(obj: &'a Value, key: &str) -> Result<&'a [Value], String> {
    match obj.get(key) {
        None | Some(Value::Null) => Ok(&[]),
        Some(Value::Array(a)) => Ok(a),
        Some(v) => Err(format!("`{key}` must be an array, found {}", describe(v))),
    }
}

/// Optional fixed-length numeric array property `key` (a factor, vector or matrix).
pub(super) fn numbers<const N: usize>(obj: &Value, key: &str) -> Result<Option<[f64; N]>, String> {
    let Some(v) = obj.get(key) else {
        return Ok(None);
    };
    let bad = || {
        format!(
            "`{key}` must be an array of {N} numbers, found {}",
            describe(v)
        )
    };
    let a = v.as_array().ok_or_else(bad)?;
    if a.len() != N {
        return Err(bad());
    }
    let mut out = [0.0; N];
    for (o, x) in out.iter_mut().zip(a) {
        *o = x.as_f64().ok_or_else(bad)?;
    }
    Ok(Some(out))
}

/// The object `obj.extensions.<name>`, if present and an object.
pub(super) fn extension<'a>(obj: &'a Value, name: &str) -> Option<&'a Value> {
    obj.get("extensions")?.get(name).filter(|v| v.is_object())
}

/// The `name` property of an object, when it is a non-empty string.
pub(super) fn name(obj: &Value) -> Option<&str> {
    obj.get("name")
        .and_then(Value::as_str)
        .filter(|s| !s.is_empty())
}
