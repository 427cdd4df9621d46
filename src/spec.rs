//! Parsers for the small textual values that options take (`X,Y,Z` vectors, pin specs...), shared
//! by the command line and scene files so both accept exactly the same spellings.
//!
//! They know values, not the options that take them: a bad value is an [`Error::Value`], to which
//! the job layer, knowing the option, attaches it ([`Error::for_param`]). Lower layers parse their
//! specifications (pins, colliders, limits) with them too.

use glam::DVec3;

use crate::error::{Error, Result};

/// Parses `N` comma-separated finite numbers of the form `form` (named in errors).
///
/// # Errors
/// [`Error::Value`] quoting `text`.
pub fn parse_numbers<const N: usize>(text: &str, form: &str) -> Result<[f64; N]> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != N {
        return Err(Error::value(format!(
            "`{text}`: expected {N} comma-separated numbers ({form})"
        )));
    }
    let mut out = [0.0; N];
    for (slot, p) in out.iter_mut().zip(&parts) {
        *slot = p
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                Error::value(format!("`{text}`: `{p}` is not a finite number ({form})"))
            })?;
    }
    Ok(out)
}

/// Parses an `X,Y,Z` vector.
///
/// # Errors
/// As [`parse_numbers`].
pub fn parse_vec3(text: &str) -> Result<DVec3> {
    parse_numbers::<3>(text, "X,Y,Z").map(DVec3::from_array)
}

/// Checks that a number is finite and strictly positive.
///
/// # Errors
/// [`Error::Value`] otherwise.
pub fn positive(value: f64) -> Result<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(Error::value(format!("{value}: must be a positive number")))
    }
}

/// Checks that a number is finite and not negative.
///
/// # Errors
/// [`Error::Value`] otherwise.
pub fn non_negative(value: f64) -> Result<f64> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(Error::value(format!(
            "{value}: must be zero or a positive number"
        )))
    }
}

/// `X,Y,Z` as a command-line value parser and for scene files: the error is the bare reason
/// (clap and the TOML reader say which option or key it belongs to).
pub fn vec3_value(text: &str) -> std::result::Result<DVec3, String> {
    parse_vec3(text).map_err(|e| e.detail())
}

/// A value parsed by its `FromStr`, as a command-line value parser: the error is the bare
/// reason.
pub fn parsed_value<T: std::str::FromStr<Err = Error>>(
    text: &str,
) -> std::result::Result<T, String> {
    text.parse::<T>().map_err(|e| e.detail())
}

/// Serde helpers for job configs: vectors as `"X,Y,Z"` strings or `[X, Y, Z]` arrays, and
/// specifications (pins, colliders, limits...) as the strings the command line takes, so a scene
/// file and a command line accept exactly the same spellings.
pub mod de {
    use std::fmt;
    use std::str::FromStr;

    use glam::DVec3;
    use serde::de::{Error as _, IgnoredAny, MapAccess, SeqAccess, Visitor};
    use serde::{Deserialize, Deserializer};

    use crate::error::Error;

    #[derive(Deserialize)]
    #[serde(untagged)]
    enum OneOrMany {
        One(String),
        Many(Vec<String>),
    }

    /// The expected form of a vector, for messages.
    pub const VEC3_FORM: &str = "three numbers, [X, Y, Z] or \"X,Y,Z\"";

    /// An optional vector: `"X,Y,Z"` or `[X, Y, Z]`. A wrong form is a plain message giving the
    /// expected one (the reader of the scene file names the key and the line).
    pub fn opt_vec3<'de, D: Deserializer<'de>>(d: D) -> Result<Option<DVec3>, D::Error> {
        d.deserialize_any(Vec3Visitor).map(Some)
    }

    struct Vec3Visitor;

    impl<'de> Visitor<'de> for Vec3Visitor {
        type Value = DVec3;

        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str(VEC3_FORM)
        }

        fn visit_str<E: serde::de::Error>(self, s: &str) -> Result<DVec3, E> {
            super::vec3_value(s).map_err(E::custom)
        }

        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<DVec3, A::Error> {
            let mut values = Vec::new();
            while let Some(v) = seq.next_element::<Component>()? {
                values.push(v.0);
            }
            if values.len() != 3 {
                return Err(A::Error::custom(format!(
                    "expected {VEC3_FORM}; found {} value{}",
                    values.len(),
                    if values.len() == 1 { "" } else { "s" }
                )));
            }
            let mut out = [0.0; 3];
            for (i, (slot, v)) in out.iter_mut().zip(values).enumerate() {
                *slot = match v {
                    Ok(x) if x.is_finite() => x,
                    Ok(x) => {
                        return Err(A::Error::custom(format!(
                            "expected {VEC3_FORM}; value {} is {x}, not a finite number",
                            i + 1
                        )))
                    }
                    Err(found) => {
                        return Err(A::Error::custom(format!(
                            "expected {VEC3_FORM}; value {} is {found}, not a number",
                            i + 1
                        )))
                    }
                };
            }
            Ok(DVec3::from_array(out))
        }
    }

    /// One value of a vector's array: a number, or what was found instead.
    struct Component(Result<f64, String>);

    impl<'de> Deserialize<'de> for Component {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            struct V;
            impl<'de> Visitor<'de> for V {
                type Value = Component;
                fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                    f.write_str("a number")
                }
                fn visit_f64<E>(self, v: f64) -> Result<Component, E> {
                    Ok(Component(Ok(v)))
                }
                fn visit_i64<E>(self, v: i64) -> Result<Component, E> {
                    Ok(Component(Ok(v as f64)))
                }
                fn visit_u64<E>(self, v: u64) -> Result<Component, E> {
                    Ok(Component(Ok(v as f64)))
                }
                fn visit_str<E>(self, v: &str) -> Result<Component, E> {
                    Ok(Component(Err(format!("{v:?}"))))
                }
                fn visit_bool<E>(self, v: bool) -> Result<Component, E> {
                    Ok(Component(Err(v.to_string())))
                }
                fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Component, A::Error> {
                    while seq.next_element::<IgnoredAny>()?.is_some() {}
                    Ok(Component(Err("an array".into())))
                }
                fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Component, A::Error> {
                    while map.next_entry::<IgnoredAny, IgnoredAny>()?.is_some() {}
                    Ok(Component(Err("a table".into())))
                }
            }
            d.deserialize_any(V)
        }
    }

    /// A list of specifications parsed by `FromStr`: one string or an array of strings.
    pub fn spec_list<'de, D, T>(d: D) -> Result<Vec<T>, D::Error>
    where
        D: Deserializer<'de>,
        T: FromStr<Err = Error>,
    {
        string_list(d)?
            .iter()
            .map(|s| s.parse::<T>().map_err(|e| D::Error::custom(e.detail())))
            .collect()
    }

    /// A list of strings: one string or an array of strings.
    pub fn string_list<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<String>, D::Error> {
        Ok(match OneOrMany::deserialize(d)? {
            OneOrMany::One(s) => vec![s],
            OneOrMany::Many(v) => v,
        })
    }
}

/// Splits `FILE#NAME` at its last `#` when FILE names a mesh file (.obj, .gltf, .glb); a `#`
/// elsewhere stays part of the file name (`--collider mesh:FILE#NAME`, `--body FILE.glb#NAME`).
pub fn split_mesh_part(
    rest: &str,
) -> std::result::Result<(std::path::PathBuf, Option<String>), String> {
    let rest = rest.trim();
    if let Some((file, part)) = rest.rsplit_once('#') {
        let ext = std::path::Path::new(file)
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        if matches!(ext.as_deref(), Some("obj" | "gltf" | "glb")) {
            if file.trim().is_empty() {
                return Err("the mesh file name is empty".into());
            }
            let part = part.trim();
            if part.is_empty() {
                return Err(format!(
                    "the object name after `#` is empty (mesh:{file}#NAME, or mesh:{file} for every object)"
                ));
            }
            return Ok((std::path::PathBuf::from(file.trim()), Some(part.to_owned())));
        }
    }
    if rest.is_empty() {
        return Err("the mesh file name is empty".into());
    }
    Ok((std::path::PathBuf::from(rest), None))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vectors_parse_and_reject_garbage() {
        assert_eq!(
            parse_vec3("0, -9.81,0").unwrap(),
            DVec3::new(0.0, -9.81, 0.0)
        );
        for bad in ["1,2", "1,2,3,4", "a,b,c", "1,nan,2", ""] {
            let e = parse_vec3(bad).unwrap_err();
            assert!(matches!(e, Error::Value { .. }), "{e}");
            assert!(e.detail().starts_with(&format!("`{bad}`: ")), "{e}");
        }
    }
}
