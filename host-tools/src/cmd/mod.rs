//! Subcommands of `orbfix`, one module each (each has `Args` and `run`).

pub mod bench;
pub mod bench_localize;
pub mod budget;
pub mod demo;
pub mod embed;
pub mod eval;
pub mod export_geotiff;
pub mod export_tflite;
pub mod fix_report;
pub mod generate;
pub mod geotiff_info;
pub mod localize;
pub mod map;
pub mod prepare_inputs;
pub mod quantize;
pub mod render;
pub mod reproject;
pub mod results;
pub mod train;
pub mod traverse;

/// Value parsers for numbers that must be positive or non-negative. Used with
/// `allow_negative_numbers = true`, so `--noise -5` reaches the parser and is refused with
/// what is wrong, instead of being read as an unknown option `-5`.
pub mod num {
    fn parse<T: std::str::FromStr + PartialOrd + Default + Copy>(
        s: &str,
        ok: impl Fn(T) -> bool,
        what: &str,
    ) -> Result<T, String> {
        let v: T = s
            .trim()
            .parse()
            .map_err(|_| format!("'{s}' is not a number"))?;
        if ok(v) {
            Ok(v)
        } else {
            Err(format!("must be {what}, got {s}"))
        }
    }

    /// A finite number above 0.
    pub fn positive_f64(s: &str) -> Result<f64, String> {
        parse(
            s,
            |v: f64| v.is_finite() && v > 0.0,
            "a finite number above 0",
        )
    }

    /// A finite number of at least 0.
    pub fn non_negative_f64(s: &str) -> Result<f64, String> {
        parse(
            s,
            |v: f64| v.is_finite() && v >= 0.0,
            "a finite number of at least 0",
        )
    }

    /// A probability, 0 to 1.
    pub fn probability_f64(s: &str) -> Result<f64, String> {
        parse(
            s,
            |v: f64| (0.0..=1.0).contains(&v),
            "a probability from 0 to 1",
        )
    }

    /// A finite number above 0.
    pub fn positive_f32(s: &str) -> Result<f32, String> {
        parse(
            s,
            |v: f32| v.is_finite() && v > 0.0,
            "a finite number above 0",
        )
    }
}
