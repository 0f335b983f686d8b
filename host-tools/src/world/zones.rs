//! Train, validation and test zones of the world: the ONE place they are defined.
//!
//! As in the 2018 study: a 2 x 2 km training zone and two disjoint 1 x 1 km zones, here
//! separated by 500 m gaps. A rover location's 300 x 300 m map region reaches
//! [`MAP_HALF_EXTENT_M`] from the location; keep locations at least that far inside their
//! zone ([`Zone::location_area`]) so that no map, crop or view of one split touches the
//! interior of another split's zone.

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
    /// All splits, in order.
    pub const ALL: [Split; 3] = [Split::Train, Split::Validation, Split::Test];

    /// Lower-case name (`train`, `validation`, `test`).
    pub fn name(self) -> &'static str {
        zone(self).name
    }
}

impl core::fmt::Display for Split {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

impl core::str::FromStr for Split {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "train" => Ok(Split::Train),
            "validation" | "val" => Ok(Split::Validation),
            "test" => Ok(Split::Test),
            other => Err(format!(
                "unknown split '{other}': expected train, validation or test"
            )),
        }
    }
}

/// An axis-aligned rectangle of the world, `[x_min_m, x_max_m) x [y_min_m, y_max_m)`, metres.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Zone {
    /// Name of the split (`train`, `validation`, `test`).
    pub name: &'static str,
    /// West edge, metres (world x).
    pub x_min_m: f64,
    /// South edge, metres (world y).
    pub y_min_m: f64,
    /// East edge, metres (exclusive).
    pub x_max_m: f64,
    /// North edge, metres (exclusive).
    pub y_max_m: f64,
}

/// Half the side of a rover location's orbital map region (300 x 300 m), metres.
pub const MAP_HALF_EXTENT_M: f64 = 150.0;

/// Side of the whole virtual world (as the study's 8 x 8 km), metres; zones lie in
/// `[0, WORLD_SIZE_M)^2`.
pub const WORLD_SIZE_M: f64 = 8000.0;

/// The training zone: 2 x 2 km.
pub const TRAIN: Zone = Zone {
    name: "train",
    x_min_m: 0.0,
    y_min_m: 0.0,
    x_max_m: 2000.0,
    y_max_m: 2000.0,
};

/// The validation zone: 1 x 1 km, 500 m east of the training zone.
pub const VALIDATION: Zone = Zone {
    name: "validation",
    x_min_m: 2500.0,
    y_min_m: 0.0,
    x_max_m: 3500.0,
    y_max_m: 1000.0,
};

/// The test zone: 1 x 1 km, 500 m north of the validation zone.
pub const TEST: Zone = Zone {
    name: "test",
    x_min_m: 2500.0,
    y_min_m: 1500.0,
    x_max_m: 3500.0,
    y_max_m: 2500.0,
};

/// All zones, in [`Split::ALL`] order.
pub const ALL: [Zone; 3] = [TRAIN, VALIDATION, TEST];

/// The zone of a split.
pub fn zone(split: Split) -> Zone {
    match split {
        Split::Train => TRAIN,
        Split::Validation => VALIDATION,
        Split::Test => TEST,
    }
}

/// The split whose zone contains `(x, y)` metres, if any.
pub fn split_at(x_m: f64, y_m: f64) -> Option<Split> {
    Split::ALL.into_iter().find(|&s| zone(s).contains(x_m, y_m))
}

impl Zone {
    /// Width (east-west), metres.
    pub fn width_m(&self) -> f64 {
        self.x_max_m - self.x_min_m
    }

    /// Height (north-south), metres.
    pub fn height_m(&self) -> f64 {
        self.y_max_m - self.y_min_m
    }

    /// Centre, metres.
    pub fn centre(&self) -> (f64, f64) {
        (
            0.5 * (self.x_min_m + self.x_max_m),
            0.5 * (self.y_min_m + self.y_max_m),
        )
    }

    /// Whether `(x, y)` lies in the zone (west and south edges inclusive).
    pub fn contains(&self, x_m: f64, y_m: f64) -> bool {
        x_m >= self.x_min_m && x_m < self.x_max_m && y_m >= self.y_min_m && y_m < self.y_max_m
    }

    /// The zone shrunk by `margin_m` on every side (may be empty: see [`Zone::is_empty`]).
    pub fn inset(&self, margin_m: f64) -> Zone {
        Zone {
            name: self.name,
            x_min_m: self.x_min_m + margin_m,
            y_min_m: self.y_min_m + margin_m,
            x_max_m: self.x_max_m - margin_m,
            y_max_m: self.y_max_m - margin_m,
        }
    }

    /// Where rover locations of this split may be drawn: the zone inset by
    /// [`MAP_HALF_EXTENT_M`], so the whole 300 m map region stays inside the zone.
    pub fn location_area(&self) -> Zone {
        self.inset(MAP_HALF_EXTENT_M)
    }

    /// Whether the zone has no area.
    pub fn is_empty(&self) -> bool {
        !(self.x_max_m > self.x_min_m && self.y_max_m > self.y_min_m)
    }

    /// Whether the interiors of two zones overlap.
    pub fn overlaps(&self, other: &Zone) -> bool {
        self.x_min_m < other.x_max_m
            && other.x_min_m < self.x_max_m
            && self.y_min_m < other.y_max_m
            && other.y_min_m < self.y_max_m
    }

    /// Gap between two zones, metres: the larger of the x and y separations (0 if they
    /// overlap or touch).
    pub fn gap_m(&self, other: &Zone) -> f64 {
        let gx = (other.x_min_m - self.x_max_m).max(self.x_min_m - other.x_max_m);
        let gy = (other.y_min_m - self.y_max_m).max(self.y_min_m - other.y_max_m);
        gx.max(gy).max(0.0)
    }
}
