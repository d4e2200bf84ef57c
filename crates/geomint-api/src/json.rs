//! Reading request bodies: JSON text into a value (serde_json with correctly rounded floats, so a
//! number sent in the shortest form that round-trips arrives with exactly its bits; a syntax
//! error, a number beyond the range of f64 included, located by serde_path_to_error), and the
//! field-by-field reader the request parsers use, which names the field at fault in every error:
//! unknown fields at any depth, missing fields, wrong types.

use std::collections::BTreeMap;

use serde_json::{Map, Value};

use crate::core::error::{ErrorCode, ErrorDetail, Field};
use crate::core::systems::ParamValue;

/// Parses JSON text into a value; errors are `malformed_json`, with the path of the value where
/// the text went wrong when there is one (`q0[2]` for a number beyond ±1.8e308, `h` for a key
/// given twice: which of the two was meant is not for the server to guess).
pub fn parse_json(bytes: &[u8]) -> Result<Value, ErrorDetail> {
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let Strict(value) = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        // A text cut short has no place where it went wrong: the rest is missing.
        let path = e.path().to_string();
        let located = path != "." && !e.inner().is_eof();
        malformed(bytes, e.inner(), located.then_some(path))
    })?;
    de.end().map_err(|e| malformed(bytes, &e, None))?;
    Ok(value)
}

/// A JSON value read like `serde_json::Value`, except that an object with a key twice is an
/// error rather than its last value silently winning.
struct Strict(Value);

impl<'de> serde::Deserialize<'de> for Strict {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_any(StrictVisitor).map(Strict)
    }
}

struct StrictVisitor;

impl<'de> serde::de::Visitor<'de> for StrictVisitor {
    type Value = Value;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_bool<E>(self, v: bool) -> Result<Value, E> {
        Ok(Value::Bool(v))
    }
    fn visit_i64<E>(self, v: i64) -> Result<Value, E> {
        Ok(Value::from(v))
    }
    fn visit_u64<E>(self, v: u64) -> Result<Value, E> {
        Ok(Value::from(v))
    }
    fn visit_f64<E>(self, v: f64) -> Result<Value, E> {
        Ok(serde_json::Number::from_f64(v).map_or(Value::Null, Value::Number))
    }
    fn visit_str<E>(self, v: &str) -> Result<Value, E> {
        Ok(Value::String(v.to_string()))
    }
    fn visit_string<E>(self, v: String) -> Result<Value, E> {
        Ok(Value::String(v))
    }
    fn visit_unit<E>(self) -> Result<Value, E> {
        Ok(Value::Null)
    }
    fn visit_none<E>(self) -> Result<Value, E> {
        Ok(Value::Null)
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Value, A::Error> {
        let mut items = Vec::new();
        while let Some(Strict(item)) = seq.next_element()? {
            items.push(item);
        }
        Ok(Value::Array(items))
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<Value, A::Error> {
        let mut object = serde_json::Map::new();
        while let Some(key) = map.next_key::<String>()? {
            if object.contains_key(&key) {
                return Err(serde::de::Error::custom(format!(
                    "the key `{key}` is given twice"
                )));
            }
            let Strict(value) = map.next_value()?;
            object.insert(key, value);
        }
        Ok(Value::Object(object))
    }
}

fn malformed(bytes: &[u8], e: &serde_json::Error, path: Option<String>) -> ErrorDetail {
    if e.is_eof() && bytes.iter().all(u8::is_ascii_whitespace) {
        return ErrorDetail::new(
            ErrorCode::MalformedJson,
            "the input is empty; expected a JSON object",
        );
    }
    match path {
        Some(path) => ErrorDetail::at(
            ErrorCode::MalformedJson,
            &path,
            format!("{path}: malformed JSON: {e}"),
        ),
        None => ErrorDetail::new(ErrorCode::MalformedJson, format!("malformed JSON: {e}")),
    }
}

/// What a value is, for messages.
fn describe(v: &Value) -> String {
    match v {
        Value::Null => "null".to_string(),
        Value::Bool(b) => format!("the boolean {b}"),
        Value::Number(n) => format!("the number {n}"),
        Value::String(s) if s.chars().count() <= 40 => {
            format!("the string {}", Value::from(s.as_str()))
        }
        Value::String(_) => "a string".to_string(),
        Value::Array(_) => "a list".to_string(),
        Value::Object(_) => "an object".to_string(),
    }
}

/// An `invalid_type` error: `field` should have been `expected`.
pub fn wrong_type(field: &Field, expected: &str, v: &Value) -> ErrorDetail {
    ErrorDetail::at(
        ErrorCode::InvalidType,
        field,
        format!("{field}: expected {expected}, got {}", describe(v)),
    )
}

/// A `missing_field` error for `field`, explaining `what` it is.
pub fn missing(field: &Field, what: &str) -> ErrorDetail {
    ErrorDetail::at(
        ErrorCode::MissingField,
        field,
        format!("missing field `{field}`: {what}"),
    )
}

/// An object of a request, read field by field: every reader names the field it reads, and
/// [`Obj::new`] refuses fields the request type does not have.
pub struct Obj<'a> {
    map: &'a Map<String, Value>,
    at: Field,
}

impl<'a> Obj<'a> {
    /// `v` as an object named `at` (the empty field for the request itself), refusing keys not
    /// in `allowed` (`unknown_field`).
    pub fn new(v: &'a Value, at: Field, allowed: &[&str]) -> Result<Self, ErrorDetail> {
        let map = v.as_object().ok_or_else(|| {
            if at.as_str().is_empty() {
                ErrorDetail::new(
                    ErrorCode::InvalidType,
                    format!("the request must be a JSON object, got {}", describe(v)),
                )
            } else {
                wrong_type(&at, "an object", v)
            }
        })?;
        if let Some(k) = map.keys().find(|k| !allowed.contains(&k.as_str())) {
            let field = at.key(k);
            return Err(ErrorDetail::at(
                ErrorCode::UnknownField,
                &field,
                format!(
                    "unknown field `{field}`; expected one of: {}",
                    allowed.join(", ")
                ),
            ));
        }
        Ok(Obj { map, at })
    }

    /// The path of member `key`.
    pub fn field(&self, key: &str) -> Field {
        self.at.key(key)
    }

    /// Member `key`, treating an explicit `null` as absent.
    pub fn get(&self, key: &str) -> Option<&'a Value> {
        self.map.get(key).filter(|v| !v.is_null())
    }

    /// Whether member `key` is given (not absent, not null).
    pub fn has(&self, key: &str) -> bool {
        self.get(key).is_some()
    }

    /// Member `key` read by `read`, or `None` when absent.
    pub fn optional<T>(
        &self,
        key: &str,
        read: impl FnOnce(&'a Value, &Field) -> Result<T, ErrorDetail>,
    ) -> Result<Option<T>, ErrorDetail> {
        self.get(key).map(|v| read(v, &self.field(key))).transpose()
    }

    /// Member `key` read by `read`; `missing_field` (explaining `what` it is) when absent.
    pub fn required<T>(
        &self,
        key: &str,
        what: &str,
        read: impl FnOnce(&'a Value, &Field) -> Result<T, ErrorDetail>,
    ) -> Result<T, ErrorDetail> {
        match self.get(key) {
            Some(v) => read(v, &self.field(key)),
            None => Err(missing(&self.field(key), what)),
        }
    }
}

/// `v` as a string.
pub fn string(v: &Value, field: &Field) -> Result<String, ErrorDetail> {
    v.as_str()
        .map(str::to_string)
        .ok_or_else(|| wrong_type(field, "a string", v))
}

/// `v` as a number.
pub fn number(v: &Value, field: &Field) -> Result<f64, ErrorDetail> {
    v.as_f64().ok_or_else(|| wrong_type(field, "a number", v))
}

/// `v` as true or false.
pub fn boolean(v: &Value, field: &Field) -> Result<bool, ErrorDetail> {
    v.as_bool()
        .ok_or_else(|| wrong_type(field, "true or false", v))
}

/// `v` as a whole number ≥ 0; `expected` says what it counts. A number written with a fraction
/// part or an exponent counts when its value is whole (`10.0`, `1e3`): JSON has one kind of
/// number, and JSON Schema's `integer` (the OpenAPI document's) is any whole value.
pub fn count(v: &Value, field: &Field, expected: &str) -> Result<u64, ErrorDetail> {
    /// 2⁶⁴: the first whole f64 beyond u64.
    const BEYOND_U64: f64 = 18_446_744_073_709_551_616.0;
    let whole = |x: f64| (x.fract() == 0.0 && (0.0..BEYOND_U64).contains(&x)).then_some(x as u64);
    v.as_u64()
        .or_else(|| v.as_f64().and_then(whole))
        .ok_or_else(|| wrong_type(field, expected, v))
}

/// A list read entry by entry, each named `field[i]` in errors; `expected` describes the list.
pub fn list<T>(
    v: &Value,
    field: &Field,
    expected: &str,
    read: impl Fn(&Value, &Field) -> Result<T, ErrorDetail>,
) -> Result<Vec<T>, ErrorDetail> {
    v.as_array()
        .ok_or_else(|| wrong_type(field, expected, v))?
        .iter()
        .enumerate()
        .map(|(i, x)| read(x, &field.index(i)))
        .collect()
}

/// A list of numbers, each named `field[i]` in errors.
pub fn numbers(v: &Value, field: &Field) -> Result<Vec<f64>, ErrorDetail> {
    list(v, field, "a list of numbers", number)
}

/// System parameters: an object of numbers, names and lists of numbers; their kinds and ranges
/// are checked against the system later.
pub fn params(v: &Value, field: &Field) -> Result<BTreeMap<String, ParamValue>, ErrorDetail> {
    let map = v
        .as_object()
        .ok_or_else(|| wrong_type(field, "an object", v))?;
    Ok(map
        .iter()
        .map(|(name, v)| {
            let value = match v {
                Value::Number(n) => n.as_f64().map_or(ParamValue::Other, ParamValue::Number),
                Value::String(s) => ParamValue::Text(s.clone()),
                Value::Array(items) => items
                    .iter()
                    .map(Value::as_f64)
                    .collect::<Option<Vec<f64>>>()
                    .map_or(ParamValue::Other, ParamValue::Numbers),
                _ => ParamValue::Other,
            };
            (name.clone(), value)
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn floats_arrive_with_their_exact_bits() {
        let xs: Vec<f64> = (0..2000)
            .map(|i| 1.0 + 0.1 * i as f64)
            .chain([3.8000000000000003, -2.2250738585072014e-308, 0.1 + 0.2])
            .collect();
        let text =
            serde_json::to_string(&json!({"a": {"b": [xs.clone()]}, "c\\\"": xs[5], "n": 10}))
                .unwrap();
        let v = parse_json(text.as_bytes()).unwrap();
        let back: Vec<f64> = serde_json::from_value(v["a"]["b"][0].clone()).unwrap();
        assert!(xs
            .iter()
            .zip(&back)
            .all(|(x, y)| x.to_bits() == y.to_bits()));
        assert_eq!(v["c\\\""].as_f64().unwrap().to_bits(), xs[5].to_bits());
        assert_eq!(v["n"].as_u64(), Some(10));
    }

    #[test]
    fn counts_take_whole_values_in_any_notation() {
        let at = Field::new("n");
        let read = |text: &str| count(&parse_json(text.as_bytes()).unwrap(), &at, "a count");
        assert_eq!(read("215.0").unwrap(), 215);
        assert_eq!(read("1e3").unwrap(), 1000);
        assert_eq!(read("-0.0").unwrap(), 0);
        assert_eq!(read("18446744073709551615").unwrap(), u64::MAX);
        assert_eq!(read("9.2233720368547758e18").unwrap(), 1 << 63);
        for refused in [
            "2.5",
            "-1",
            "-1.0",
            "1.8446744073709552e19",
            "1e300",
            "\"3\"",
            "true",
        ] {
            let e = read(refused).unwrap_err();
            assert_eq!(
                (e.code, e.field.as_deref()),
                (ErrorCode::InvalidType, Some("n")),
                "{refused}"
            );
        }
    }

    #[test]
    fn out_of_range_numbers_are_located() {
        let field_of = |text: &str| parse_json(text.as_bytes()).unwrap_err().field;
        assert_eq!(field_of(r#"{"h": 1e999}"#).as_deref(), Some("h"));
        assert_eq!(
            field_of(r#"{"system": "x", "q0": [1, 2, -1e999]}"#).as_deref(),
            Some("q0[2]")
        );
        assert_eq!(
            field_of("{\"params\": {\"a\": [1], \"omega\":\n 1e400}}").as_deref(),
            Some("params.omega")
        );
        let empty = parse_json(b"  ").unwrap_err();
        assert_eq!(empty.code, ErrorCode::MalformedJson);
        assert_eq!(empty.field, None);
        assert!(parse_json(b"{} x").is_err());
    }
}
