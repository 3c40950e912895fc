//! Limits on every quantity that sizes an allocation or a loop, checked before the work starts so
//! that no input can make a command run for more than a few seconds or use more than a few
//! hundred MB (docs/ARCHITECTURE.md, "Limits"). Each is far above what a winding cell needs: the
//! thesis winds 50 segments over a 350 mm mandrel.

use crate::Error;

/// Most equal-length segments of one path (the thesis uses 50; a robot program holds far fewer).
pub const MAX_SEGMENTS: usize = 10_000;
/// Most segments of all paths of one job or coverage set together (a plan costs about 60 µs and
/// 350 bytes per segment on a mesh mandrel, and its control files about 170 bytes).
pub const MAX_JOB_SEGMENTS: usize = 50_000;
/// Longest fibre path, mm (100 m: a path that long winds a mandrel hundreds of times).
pub const MAX_PATH_LENGTH_MM: f64 = 100_000.0;
/// Most samples of one path (integrator steps, helix samples, resampled points).
pub const MAX_PATH_SAMPLES: usize = 400_000;
/// Most spine knots (Table 6.1 has 36).
pub const MAX_SPINE_KNOTS: usize = 1_000;
/// Most triangles of a mesh that windcell reads from a file or generates with TRIASYM: 5 million,
/// a mandrel exported from CAD or scanned (the shipped S-bend mesh has 36 000). Memory grows
/// with the triangle count, bounded per triangle (docs/ARCHITECTURE.md, "Limits").
pub const MAX_TRIANGLES: usize = 5_000_000;

/// `Ok` when `value` is at most `limit`, else [`Error::OverLimit`] naming `name`.
pub fn at_most(name: &'static str, value: f64, limit: f64) -> Result<(), Error> {
    if value <= limit {
        Ok(())
    } else {
        Err(Error::OverLimit { name, value, limit })
    }
}

/// How a number reads in a message: plain between 1e-4 and 1e9, with at most 9 significant digits
/// and 6 decimals (trailing zeros dropped), else in exponent form with 6 significant digits, so no
/// message carries a 300-digit number.
pub fn shown(value: f64) -> String {
    let magnitude = value.abs();
    if !value.is_finite() || value == 0.0 {
        return format!("{value}");
    }
    let text = if (1e-4..1e9).contains(&magnitude) {
        let decimals = (8 - magnitude.log10().floor() as i32).clamp(0, 6) as usize;
        format!("{value:.decimals$}")
    } else {
        let e = format!("{value:.5e}");
        let (mantissa, exponent) = e.split_once('e').unwrap_or((&e, "0"));
        let mantissa = trim_zeros(mantissa);
        return format!("{mantissa}e{exponent}");
    };
    trim_zeros(&text).to_string()
}

/// A number to `decimals` places, as a report prints a measured figure, unless it is too large
/// or too small for that to read (below 1e-4 or from 1e9, zero aside): then as [`shown`] writes it.
pub fn fixed(value: f64, decimals: usize) -> String {
    let magnitude = value.abs();
    if value == 0.0 || (1e-4..1e9).contains(&magnitude) {
        format!("{value:.decimals$}")
    } else {
        shown(value)
    }
}

fn trim_zeros(text: &str) -> &str {
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.')
    } else {
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_places_unless_the_number_is_extreme() {
        assert_eq!(fixed(1005.0, 2), "1005.00");
        assert_eq!(fixed(0.021413, 5), "0.02141");
        assert_eq!(fixed(0.0, 3), "0.000");
        assert_eq!(fixed(-2.5, 1), "-2.5");
        assert_eq!(fixed(1e308, 2), "1e308");
        assert_eq!(fixed(1e-300, 3), "1e-300");
        assert_eq!(fixed(f64::INFINITY, 2), "inf");
        assert_eq!(fixed(999_999_999.0, 1), "999999999.0");
        assert_eq!(fixed(1e9, 1), "1e9");
    }

    #[test]
    fn numbers_read_short() {
        assert_eq!(shown(1e308), "1e308");
        assert_eq!(shown(-1.5e-300), "-1.5e-300");
        assert_eq!(shown(2000.0), "2000");
        assert_eq!(shown(0.1 + 0.2), "0.3");
        assert_eq!(shown(89.99999), "89.99999");
        assert_eq!(shown(123_456_789.0), "123456789");
        assert_eq!(shown(101_986_487.528_729), "101986488");
        assert_eq!(shown(1_234.567_891_23), "1234.56789");
        assert_eq!(shown(1.234_567_89e9), "1.23457e9");
        assert_eq!(shown(0.0), "0");
        assert_eq!(shown(f64::NAN), "NaN");
        assert_eq!(shown(f64::NEG_INFINITY), "-inf");
    }

    #[test]
    fn limits_name_value_and_limit() {
        assert!(at_most("segments", 10_000.0, 10_000.0).is_ok());
        let e = at_most("segments", 1e9, 1e4).unwrap_err();
        assert_eq!(
            e.to_string(),
            "segments = 1e9 exceeds the limit of 10000 (docs/ARCHITECTURE.md, \"Limits\")"
        );
        assert!(at_most("x", f64::NAN, 1.0).is_err());
    }
}
