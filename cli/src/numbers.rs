//! Checks of numeric command-line values and compact number formatting.

use anyhow::{bail, Result};

/// `value` if it is finite and > 0, else an error naming `flag`.
pub fn positive(flag: &str, value: f64) -> Result<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        bail!("{flag} must be a finite number > 0 (got {value})")
    }
}

/// `value` if it is finite and ≥ 0, else an error naming `flag`.
pub fn non_negative(flag: &str, value: f64) -> Result<f64> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        bail!("{flag} must be a finite number ≥ 0 (got {value})")
    }
}

/// `value` if it is finite, else an error naming `flag`.
pub fn finite(flag: &str, value: f64) -> Result<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        bail!("{flag} must be a finite number (got {value})")
    }
}

/// `value` with at most `decimals` decimals and no trailing zeros: `0.7`, `25`, `1.66`.
pub fn trim(value: f64, decimals: usize) -> String {
    let s = format!("{value:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    if s == "-0" {
        "0".to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trims_trailing_zeros() {
        assert_eq!(trim(0.7e-3 * 1e3, 6), "0.7");
        assert_eq!(trim(25.0, 3), "25");
        assert_eq!(trim(1.66, 3), "1.66");
        assert_eq!(trim(-0.0001, 2), "0");
        assert_eq!(trim(9257.142857, 1), "9257.1");
    }

    #[test]
    fn rejects_bad_values() {
        assert!(positive("--gap", 0.0).is_err());
        assert!(positive("--gap", f64::NAN).is_err());
        assert!(non_negative("--noise", -1.0).is_err());
        assert!(finite("--temperature", f64::INFINITY).is_err());
        assert_eq!(positive("--gap", 1e-3).unwrap(), 1e-3);
    }
}
