//! Parsers for the small textual values that options take (`X,Y,Z` vectors, pin specs...), shared
//! by the command line and scene files so both accept exactly the same spellings.

use glam::DVec3;

use crate::error::{Error, Result};

/// Parses `N` comma-separated finite numbers; `option` names the option in errors.
pub fn parse_numbers<const N: usize>(option: &str, text: &str, form: &str) -> Result<[f64; N]> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != N {
        return Err(Error::option(
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
                Error::option(
                    option,
                    format!("`{text}`: `{p}` is not a finite number ({form})"),
                )
            })?;
    }
    Ok(out)
}

/// Parses an `X,Y,Z` vector.
pub fn parse_vec3(option: &str, text: &str) -> Result<DVec3> {
    parse_numbers::<3>(option, text, "X,Y,Z").map(DVec3::from_array)
}

/// Checks that a number is finite and strictly positive.
pub fn positive(option: &str, value: f64) -> Result<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(Error::option(
            option,
            format!("{value}: must be a positive number"),
        ))
    }
}

/// Checks that a number is finite and not negative.
pub fn non_negative(option: &str, value: f64) -> Result<f64> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(Error::option(
            option,
            format!("{value}: must be zero or a positive number"),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vectors_parse_and_reject_garbage() {
        assert_eq!(
            parse_vec3("--gravity", "0, -9.81,0").unwrap(),
            DVec3::new(0.0, -9.81, 0.0)
        );
        for bad in ["1,2", "1,2,3,4", "a,b,c", "1,nan,2", ""] {
            let e = parse_vec3("--gravity", bad).unwrap_err().to_string();
            assert!(e.contains("--gravity"), "{e}");
        }
    }
}
