//! Reading a JSON object field by field, so that every error names the
//! field's whole path (`volume.g`, `lights[0].intensity`): missing and
//! unknown fields, wrong types, and NaN or infinity, which JSON cannot
//! spell (serializers write them as `null`, Python's `json` as a bare `NaN`).

use crate::bail;
use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use serde_json::{Map, Value};

/// What to say where a number was NaN or infinite in the program that wrote the file.
const NOT_FINITE: &str = "JSON has no NaN or infinity (writers put null or NaN there): give a finite number";

/// The fields of one JSON object, at `path` in the file.
pub(crate) struct Fields<'a> {
    map: &'a Map<String, Value>,
    path: String,
}

impl<'a> Fields<'a> {
    /// The object `value` at `path` (`""` at the top); every key must be one of `known`.
    pub fn new(value: &'a Value, path: &str, known: &[&str]) -> Result<Self> {
        let Some(map) = value.as_object() else {
            bail!("{}: {} is not an object {{...}}", if path.is_empty() { "scene" } else { path }, kind(value));
        };
        let fields = Fields { map, path: path.into() };
        if let Some(key) = map.keys().find(|k| !known.contains(&k.as_str())) {
            bail!("{}: unknown field (expected one of: {})", fields.name(key), known.join(", "));
        }
        Ok(fields)
    }

    /// The object `value` at `path`, whatever other keys it holds (files
    /// written by other programs carry keys this project does not read).
    pub fn lenient(value: &'a Value, path: &str) -> Result<Self> {
        let Some(map) = value.as_object() else {
            bail!("{}: {} is not an object {{...}}", if path.is_empty() { "file" } else { path }, kind(value));
        };
        Ok(Fields { map, path: path.into() })
    }

    /// The path of field `key`.
    pub fn name(&self, key: &str) -> String {
        if self.path.is_empty() {
            key.into()
        } else {
            format!("{}.{key}", self.path)
        }
    }

    /// The raw value of an optional field.
    pub fn get(&self, key: &str) -> Option<&'a Value> {
        self.map.get(key)
    }

    /// The raw value of a required field.
    pub fn value(&self, key: &str) -> Result<&'a Value> {
        self.map.get(key).ok_or_else(|| Error(format!("{}: missing (this field is required)", self.name(key))))
    }

    /// A required field.
    pub fn required<T: DeserializeOwned>(&self, key: &str) -> Result<T> {
        self.convert(key, self.value(key)?)
    }

    /// An optional field: `None` if absent.
    pub fn optional<T: DeserializeOwned>(&self, key: &str) -> Result<Option<T>> {
        self.map.get(key).map(|v| self.convert(key, v)).transpose()
    }

    /// An optional count that may be written as an integer or as a whole
    /// number in floating-point notation (`1e6`, which JSON writers and
    /// people use for large counts).
    pub fn optional_count(&self, key: &str) -> Result<Option<u64>> {
        let Some(v) = self.map.get(key) else { return Ok(None) };
        let whole = |x: f64| x >= 0.0 && x.fract() == 0.0 && x < u64::MAX as f64;
        match v.as_u64().or_else(|| v.as_f64().filter(|&x| whole(x)).map(|x| x as u64)) {
            Some(n) => Ok(Some(n)),
            None if v.is_null() => bail!("{}: is null or NaN; {NOT_FINITE}", self.name(key)),
            None => bail!("{}: {v} is not a whole number >= 0", self.name(key)),
        }
    }

    /// The items of a required list field, each with its path (`lights[0]`).
    pub fn list(&self, key: &str) -> Result<Vec<(String, &'a Value)>> {
        let v = self.value(key)?;
        let Some(items) = v.as_array() else { bail!("{}: {} is not a list [...]", self.name(key), kind(v)) };
        Ok(items.iter().enumerate().map(|(n, item)| (format!("{}[{n}]", self.name(key)), item)).collect())
    }

    fn convert<T: DeserializeOwned>(&self, key: &str, v: &Value) -> Result<T> {
        T::deserialize(v).map_err(|e| match v {
            Value::Null => Error(format!("{}: is null or NaN; {NOT_FINITE}", self.name(key))),
            _ if has_null(v) => Error(format!("{}: {v} holds null or NaN; {NOT_FINITE}", self.name(key))),
            _ => Error(format!("{}: {e}", self.name(key))),
        })
    }
}

fn has_null(v: &Value) -> bool {
    match v {
        Value::Null => true,
        Value::Array(items) => items.iter().any(has_null),
        _ => false,
    }
}

fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "a list",
        Value::Object(_) => "an object",
    }
}

/// JSON text parsed; a bare `NaN` or `Infinity` becomes `null`, so that the
/// field reader names the field.
pub(crate) fn parse_json(text: &str) -> std::result::Result<Value, serde_json::Error> {
    serde_json::from_str(text).or_else(|e| nan_as_null(text).and_then(|t| serde_json::from_str(&t).ok()).ok_or(e))
}

/// `text` with every bare `NaN`, `Infinity` or `-Infinity` outside strings
/// written as `null` (so the field reader can name the field), or `None`
/// if there is none.
pub(crate) fn nan_as_null(text: &str) -> Option<String> {
    let mut out = String::with_capacity(text.len());
    let (mut in_string, mut escaped, mut found) = (false, false, false);
    let mut rest = text;
    while let Some(c) = rest.chars().next() {
        if in_string {
            (in_string, escaped) = (escaped || c != '"', !escaped && c == '\\');
        } else if c == '"' {
            in_string = true;
        } else if let Some(token) = ["NaN", "Infinity", "-Infinity"].into_iter().find(|t| rest.starts_with(t)) {
            out.push_str("null");
            rest = &rest[token.len()..];
            found = true;
            continue;
        }
        out.push(c);
        rest = &rest[c.len_utf8()..];
    }
    found.then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn errors_name_the_path() {
        let v = json!({"a": 1.5, "b": null, "c": [1.0, null], "d": "x", "e": 1e6, "f": 2.5});
        let f = Fields::new(&v, "volume", &["a", "b", "c", "d", "e", "f"]).unwrap();
        assert_eq!(f.required::<f64>("a"), Ok(1.5));
        let e = f.required::<f64>("b").unwrap_err().0;
        assert_eq!(e, format!("volume.b: is null or NaN; {NOT_FINITE}"));
        let e = f.required::<[f64; 2]>("c").unwrap_err().0;
        assert_eq!(e, format!("volume.c: [1.0,null] holds null or NaN; {NOT_FINITE}"));
        assert!(f.required::<f64>("d").unwrap_err().0.starts_with("volume.d: invalid type: string"));
        assert_eq!(f.required::<f64>("z").unwrap_err().0, "volume.z: missing (this field is required)");
        assert_eq!(f.optional::<f64>("z"), Ok(None));
        assert_eq!(f.optional_count("e"), Ok(Some(1_000_000)));
        assert_eq!(f.optional_count("f").unwrap_err().0, "volume.f: 2.5 is not a whole number >= 0");
        let e = Fields::new(&v, "lights[0]", &["a"]).err().unwrap().0;
        assert!(e.starts_with("lights[0].b: unknown field"), "{e}");
    }

    #[test]
    fn bare_nan_outside_strings_becomes_null() {
        assert_eq!(nan_as_null(r#"{"a": 1}"#), None);
        let t = nan_as_null(r#"{"s": "NaN \"Infinity\"", "g": NaN, "p": [-Infinity, Infinity]}"#).unwrap();
        assert_eq!(t, r#"{"s": "NaN \"Infinity\"", "g": null, "p": [null, null]}"#);
    }
}
