//! Disjoint train / validation / test zones of the world (metres, world frame).

use serde::{Deserialize, Serialize};

/// A dataset split.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Split {
    /// Training zone.
    Train,
    /// Validation zone.
    Validation,
    /// Test zone.
    Test,
}

impl Split {
    /// The three splits in order.
    pub const ALL: [Split; 3] = [Split::Train, Split::Validation, Split::Test];
}

/// An axis-aligned rectangle of the world, metres.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Zone {
    /// Split name.
    pub name: &'static str,
    /// West edge, metres.
    pub x_min_m: f64,
    /// South edge, metres.
    pub y_min_m: f64,
    /// East edge, metres.
    pub x_max_m: f64,
    /// North edge, metres.
    pub y_max_m: f64,
}

/// The zone of a split: as in the study, 2 x 2 km for training and 1 x 1 km each for
/// validation and test, disjoint.
pub fn zone(split: Split) -> Zone {
    match split {
        Split::Train => Zone {
            name: "train",
            x_min_m: 0.0,
            y_min_m: 0.0,
            x_max_m: 2000.0,
            y_max_m: 2000.0,
        },
        Split::Validation => Zone {
            name: "validation",
            x_min_m: 2500.0,
            y_min_m: 0.0,
            x_max_m: 3500.0,
            y_max_m: 1000.0,
        },
        Split::Test => Zone {
            name: "test",
            x_min_m: 2500.0,
            y_min_m: 1500.0,
            x_max_m: 3500.0,
            y_max_m: 2500.0,
        },
    }
}
