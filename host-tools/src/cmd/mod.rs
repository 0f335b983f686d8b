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

/// The width in pixels of a square raster of `size_m` metres at `m_per_px`, centred on
/// (`x`, `y`) metres, after checking the options (`--x`, `--y`, `--size-m`, `--m-per-px`):
/// finite, positive, and 8 to 16,384 pixels wide. `what` names the raster in the error.
pub(crate) fn square_raster_px(
    x: f64,
    y: f64,
    size_m: f64,
    m_per_px: f64,
    what: &str,
) -> anyhow::Result<usize> {
    anyhow::ensure!(
        x.is_finite() && y.is_finite(),
        "--x and --y must be finite metres"
    );
    anyhow::ensure!(
        m_per_px.is_finite() && m_per_px > 0.0 && size_m.is_finite() && size_m > 0.0,
        "--size-m and --m-per-px must be positive metres"
    );
    let px = (size_m / m_per_px).round() as usize;
    anyhow::ensure!(
        (8..=16384).contains(&px),
        "{what} would be {px} px wide: choose --size-m / --m-per-px between 8 and 16384"
    );
    Ok(px)
}

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

#[cfg(test)]
mod tests {
    use super::square_raster_px;

    #[test]
    fn square_raster_sizes_are_checked() {
        assert_eq!(
            square_raster_px(3000.0, 2000.0, 300.0, 0.25, "the map").unwrap(),
            1200
        );
        let err = |x: f64, s: f64, r: f64| {
            square_raster_px(x, 0.0, s, r, "the map")
                .unwrap_err()
                .to_string()
        };
        assert!(err(f64::NAN, 300.0, 0.25).contains("--x and --y"));
        assert!(err(0.0, 300.0, 0.0).contains("positive"));
        assert!(err(0.0, -1.0, 0.25).contains("positive"));
        assert!(err(0.0, 1.0, 0.25).contains("the map would be 4 px wide"));
        assert!(err(0.0, 5000.0, 0.25).contains("20000 px wide"));
    }
}
