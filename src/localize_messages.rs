//! Messages of the localizer's errors: `Display` and `core::error::Error` for
//! [`crate::localize::LocalizeError`] (kept beside `localize.rs` so that the lead's rewrite of
//! that file and this text do not collide; move it into `localize.rs` when convenient).

use crate::localize::LocalizeError;

impl core::fmt::Display for LocalizeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Match(e) => write!(f, "{e}"),
            Self::ResolutionMismatch {
                map_m_per_px,
                top_m_per_px,
            } => write!(
                f,
                "the map has {map_m_per_px} m per pixel but the top-down image {top_m_per_px}; give both the same resolution"
            ),
            Self::PriorOutsideMap => write!(
                f,
                "the prior position is outside the map; give a prior inside the map or a map that covers it"
            ),
            Self::TooLittleCoverage { permille } => write!(
                f,
                "only {}.{}% of the top-down image has data, below the configured minimum; check the cameras",
                permille / 10,
                permille % 10
            ),
            Self::BadConfig => write!(
                f,
                "the localizer configuration does not fit the images: the template side must be a multiple of the coarse factor, the coarse factor a multiple of the fine factor, and both factors 1 to 257"
            ),
            Self::ScratchTooSmall => write!(
                f,
                "the localizer's scratch buffers are smaller than buffer_sizes asks; size them with buffer_sizes"
            ),
        }
    }
}

impl core::error::Error for LocalizeError {}
