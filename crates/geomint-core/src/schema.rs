//! OpenAPI schemas of the core's catalogue-driven types (method, system and chart ids), built
//! from the catalogues themselves so that the published document lists exactly the values the
//! core accepts.

use utoipa::openapi::schema::{ObjectBuilder, Schema, Type};
use utoipa::openapi::RefOr;

/// A string schema that admits exactly `values`.
pub fn string_enum<'a>(description: &str, values: impl Iterator<Item = &'a str>) -> RefOr<Schema> {
    ObjectBuilder::new()
        .schema_type(Type::String)
        .description(Some(description))
        .enum_values(Some(values.map(str::to_string).collect::<Vec<_>>()))
        .into()
}
