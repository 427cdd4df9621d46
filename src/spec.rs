//! Parsers for the small textual values that options take (`X,Y,Z` vectors, pin specs...), shared
//! by the command line and scene files so both accept exactly the same spellings.

use glam::DVec3;

use crate::error::{Error, Result};
use crate::param::Param;

/// Parses `N` comma-separated finite numbers; `option` is the parameter named in errors.
pub fn parse_numbers<const N: usize>(option: Param, text: &str, form: &str) -> Result<[f64; N]> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != N {
        return Err(Error::param_value(
            option,
            format!("`{text}`: expected {N} comma-separated numbers ({form})"),
        ));
    }
    let mut out = [0.0; N];
    for (slot, p) in out.iter_mut().zip(&parts) {
        *slot = p
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                Error::param_value(
                    option,
                    format!("`{text}`: `{p}` is not a finite number ({form})"),
                )
            })?;
    }
    Ok(out)
}

/// Parses an `X,Y,Z` vector.
pub fn parse_vec3(option: Param, text: &str) -> Result<DVec3> {
    parse_numbers::<3>(option, text, "X,Y,Z").map(DVec3::from_array)
}

/// Checks that a number is finite and strictly positive.
pub fn positive(option: Param, value: f64) -> Result<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(Error::param_value(
            option,
            format!("{value}: must be a positive number"),
        ))
    }
}

/// Checks that a number is finite and not negative.
pub fn non_negative(option: Param, value: f64) -> Result<f64> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(Error::param_value(
            option,
            format!("{value}: must be zero or a positive number"),
        ))
    }
}

/// `X,Y,Z` as a command-line value parser and for scene files: the error is the bare reason
/// (clap and the TOML reader say which option or key it belongs to).
pub fn vec3_value(text: &str) -> std::result::Result<DVec3, String> {
    parse_numbers::<3>(Param::Gravity, text, "X,Y,Z")
        .map(DVec3::from_array)
        .map_err(|e| e.detail())
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
    use std::str::FromStr;

    use glam::DVec3;
    use serde::de::Error as _;
    use serde::{Deserialize, Deserializer};

    use crate::error::Error;

    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Vec3Repr {
        Text(String),
        Array([f64; 3]),
    }

    #[derive(Deserialize)]
    #[serde(untagged)]
    enum OneOrMany {
        One(String),
        Many(Vec<String>),
    }

    /// An optional vector: `"X,Y,Z"` or `[X, Y, Z]`.
    pub fn opt_vec3<'de, D: Deserializer<'de>>(d: D) -> Result<Option<DVec3>, D::Error> {
        match Vec3Repr::deserialize(d)? {
            Vec3Repr::Text(s) => super::vec3_value(&s).map(Some).map_err(D::Error::custom),
            Vec3Repr::Array(a) if a.iter().all(|v| v.is_finite()) => Ok(Some(DVec3::from_array(a))),
            Vec3Repr::Array(_) => Err(D::Error::custom("the vector has a non-finite component")),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vectors_parse_and_reject_garbage() {
        assert_eq!(
            parse_vec3(Param::Gravity, "0, -9.81,0").unwrap(),
            DVec3::new(0.0, -9.81, 0.0)
        );
        for bad in ["1,2", "1,2,3,4", "a,b,c", "1,nan,2", ""] {
            let e = parse_vec3(Param::Gravity, bad).unwrap_err();
            assert_eq!(e.param(), Some(Param::Gravity), "{e}");
        }
    }
}
