//! Fusion of the fixes with odometry over a drive: a three-state extended Kalman filter
//! ([`Fusion`]) that carries the rover's position and its odometry's heading bias between
//! stops and folds in each [`FixReport`] through an innovation (Mahalanobis) gate.
//!
//! **State**: east and north position (metres) and the heading bias `b` of the odometry
//! (radians, true heading = odometry heading + `b`), with a 3 x 3 covariance.
//!
//! **Prediction** ([`Fusion::predict`]): one odometry increment is a leg of `distance_m`
//! driven at the odometry's heading `heading_deg`; the position moves by
//! `d (sin(h + b), cos(h + b))` (heading clockwise from north). The drift model adds, per
//! leg, an along-track variance `(scale_sigma d)^2` (wheel slip, scale error), a cross-track
//! random walk `walk_m2_per_m d`, and a random walk of the heading bias
//! `bias_walk_rad2_per_m d`; the Jacobian in `b` carries the bias's variance into the
//! cross-track position, so a drive with an uncertain heading grows a long, thin ellipse.
//!
//! **Update** ([`Fusion::update`]): only fixes of status ok are used. The fix's stated
//! error bound (a 95 % radius, `docs/fix.md`) becomes a per-axis standard deviation
//! `bound / bound_to_sigma` (2.45: the 95 % radius of a circular 2-D Gaussian). The
//! innovation `nu = z - (x, y)` and its covariance `S = P_xy + R` give the squared
//! Mahalanobis distance `nu' S^-1 nu`; above [`FusionConfig::gate_chi2`] (13.8: chi-square
//! with 2 degrees of freedom at 0.999) the fix is refused, so a confident fix of the wrong
//! crater field cannot pull the estimate. A refused fix inflates the position covariance
//! ([`FusionConfig::reject_inflation`]): the next stop searches a wider region, and a
//! filter that has gone wrong can be recaptured. Accepted fixes use the Joseph form (the
//! covariance stays symmetric and positive in `f32`).
//!
//! **Search radius** ([`Fusion::search_radius_m`]): `k sigma_max + margin`, clamped, where
//! `sigma_max` is the standard deviation along the position ellipse's major axis: the next
//! stop's map product needs window centres within that radius of the predicted position.
//!
//! **Why a Kalman filter**: the odometry error and the fix error are well described by
//! Gaussians once the gross errors (a wrong crater field) are gated out, the state is three
//! numbers, and the update runs once per stop (about 300 floating-point operations, against
//! about 10^8 instructions for the fix). A particle or grid filter would carry a
//! multi-modal belief, which the gate makes unnecessary here: the fix itself already
//! searched the whole region (its candidates are the modes), and a grid fine enough for
//! 0.25 m over a 250 m region is 10^6 cells of memory. The floats are on the per-stop path
//! only, not in an image loop (the core's no-float rule is for image loops); every input is
//! checked finite ([`FusionError::NonFinite`]) and a covariance that stops being positive
//! is an error ([`FusionError::Degenerate`]), never a silent NaN.

use crate::fix::{FixReport, FixStatus};
use core::fmt;

/// Settings of the filter: the drift model of the odometry, the gate and the search
/// radius.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FusionConfig {
    /// Standard deviation of the first position, per axis, metres.
    pub initial_sigma_m: f32,
    /// Standard deviation of the odometry's heading bias at the start, radians.
    pub initial_bias_sigma_rad: f32,
    /// Along-track error per metre driven (scale error and slip), dimensionless: the
    /// along-track variance of a leg of `d` metres is `(scale_sigma d)^2`.
    pub scale_sigma: f32,
    /// Cross-track random walk, square metres per metre driven.
    pub walk_m2_per_m: f32,
    /// Random walk of the heading bias, square radians per metre driven.
    pub bias_walk_rad2_per_m: f32,
    /// The fix's error bound divided by this is its per-axis standard deviation (2.45: the
    /// bound is a 95 % radius of a circular Gaussian).
    pub bound_to_sigma: f32,
    /// Squared Mahalanobis distance above which a fix is refused (13.8: chi-square, 2
    /// degrees of freedom, 0.999).
    pub gate_chi2: f32,
    /// Factor on the position covariance after a refused fix (>= 1).
    pub reject_inflation: f32,
    /// Search radius: standard deviations along the major axis.
    pub radius_sigmas: f32,
    /// Search radius: metres added (the fix's own reach around a window).
    pub radius_margin_m: f32,
    /// Smallest search radius, metres.
    pub radius_min_m: f32,
    /// Largest search radius, metres.
    pub radius_max_m: f32,
}

impl Default for FusionConfig {
    fn default() -> Self {
        Self {
            initial_sigma_m: 20.0,
            initial_bias_sigma_rad: 0.02,
            scale_sigma: 0.02,
            walk_m2_per_m: 0.0025,
            bias_walk_rad2_per_m: 1e-6,
            bound_to_sigma: 2.45,
            gate_chi2: 13.8,
            reject_inflation: 2.0,
            radius_sigmas: 3.0,
            radius_margin_m: 5.0,
            radius_min_m: 25.0,
            radius_max_m: 125.0,
        }
    }
}

impl FusionConfig {
    /// Checks every setting; the error names the first bad one.
    pub fn validate(&self) -> Result<(), FusionError> {
        let pos = |v: f32| v.is_finite() && v > 0.0;
        let nonneg = |v: f32| v.is_finite() && v >= 0.0;
        let checks: [(bool, &'static str); 12] = [
            (pos(self.initial_sigma_m), "initial_sigma_m"),
            (
                nonneg(self.initial_bias_sigma_rad),
                "initial_bias_sigma_rad",
            ),
            (nonneg(self.scale_sigma), "scale_sigma"),
            (nonneg(self.walk_m2_per_m), "walk_m2_per_m"),
            (nonneg(self.bias_walk_rad2_per_m), "bias_walk_rad2_per_m"),
            (pos(self.bound_to_sigma), "bound_to_sigma"),
            (pos(self.gate_chi2), "gate_chi2"),
            (
                self.reject_inflation.is_finite() && self.reject_inflation >= 1.0,
                "reject_inflation",
            ),
            (nonneg(self.radius_sigmas), "radius_sigmas"),
            (nonneg(self.radius_margin_m), "radius_margin_m"),
            (pos(self.radius_min_m), "radius_min_m"),
            (
                self.radius_max_m.is_finite() && self.radius_max_m >= self.radius_min_m,
                "radius_max_m",
            ),
        ];
        match checks.iter().find(|(ok, _)| !ok) {
            Some(&(_, field)) => Err(FusionError::BadConfig { field }),
            None => Ok(()),
        }
    }
}

/// One odometry increment: a straight leg as the odometry measured it.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OdometryLeg {
    /// Distance driven, metres (>= 0).
    pub distance_m: f32,
    /// Heading of the leg by the odometry, degrees clockwise from north.
    pub heading_deg: f32,
}

/// Why a fix was not folded in.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RejectReason {
    /// The fix's own status was not ok (ambiguous, no data, on border, self-check failed).
    Status(FixStatus),
    /// The fix disagrees with the prediction: squared Mahalanobis distance above the gate.
    Gate {
        /// Squared Mahalanobis distance of the innovation.
        mahalanobis2: f32,
    },
}

impl RejectReason {
    /// Name in reports.
    pub fn name(&self) -> &'static str {
        match self {
            RejectReason::Status(s) => s.name(),
            RejectReason::Gate { .. } => "innovation-gate",
        }
    }
}

impl fmt::Display for RejectReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RejectReason::Status(s) => write!(f, "the fix's status was {}", s.name()),
            RejectReason::Gate { mahalanobis2 } => write!(
                f,
                "the fix disagrees with the prediction (squared Mahalanobis distance {mahalanobis2:.1})"
            ),
        }
    }
}

/// What [`Fusion::update`] did with a fix.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UpdateOutcome {
    /// `None`: folded in; else why not.
    pub rejected: Option<RejectReason>,
    /// Squared Mahalanobis distance of the innovation (0 when the status refused it).
    pub mahalanobis2: f32,
}

impl UpdateOutcome {
    /// Whether the fix was folded in.
    pub fn accepted(&self) -> bool {
        self.rejected.is_none()
    }
}

/// Why the filter refused an input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FusionError {
    /// A setting is out of range.
    BadConfig {
        /// The setting.
        field: &'static str,
    },
    /// An input is NaN or infinite (or a distance is negative).
    NonFinite {
        /// Which input.
        what: &'static str,
    },
    /// The covariance stopped being positive definite (inputs far outside the model).
    Degenerate,
}

impl fmt::Display for FusionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::BadConfig { field } => {
                write!(f, "the fusion setting '{field}' is out of range")
            }
            Self::NonFinite { what } => write!(
                f,
                "the fusion input '{what}' is not a finite number (or is negative): check the odometry and fix values"
            ),
            Self::Degenerate => write!(
                f,
                "the fusion covariance is no longer positive: restart the filter from a known position"
            ),
        }
    }
}

impl core::error::Error for FusionError {}

type M3 = [[f32; 3]; 3];

/// The filter: position, heading bias and their covariance. Fields are private: every
/// change goes through [`Fusion::predict`] and [`Fusion::update`], which keep the
/// covariance symmetric and the state finite.
#[derive(Clone, Debug, PartialEq)]
pub struct Fusion {
    cfg: FusionConfig,
    /// `[east m, north m, heading bias rad]`.
    x: [f32; 3],
    p: M3,
    accepted: u32,
    rejected: u32,
    /// Rejections since the last accepted fix.
    streak: u32,
}

fn finite(v: f32, what: &'static str) -> Result<f32, FusionError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(FusionError::NonFinite { what })
    }
}

impl Fusion {
    /// A filter at `(x_m, y_m)` (metres) with the configured initial uncertainty.
    pub fn new(cfg: FusionConfig, x_m: f32, y_m: f32) -> Result<Self, FusionError> {
        cfg.validate()?;
        let x = finite(x_m, "x_m")?;
        let y = finite(y_m, "y_m")?;
        let s2 = cfg.initial_sigma_m * cfg.initial_sigma_m;
        let b2 = cfg.initial_bias_sigma_rad * cfg.initial_bias_sigma_rad;
        Ok(Self {
            cfg,
            x: [x, y, 0.0],
            p: [[s2, 0.0, 0.0], [0.0, s2, 0.0], [0.0, 0.0, b2]],
            accepted: 0,
            rejected: 0,
            streak: 0,
        })
    }

    /// The settings.
    pub fn config(&self) -> &FusionConfig {
        &self.cfg
    }

    /// Estimated position `(east, north)`, metres.
    pub fn position(&self) -> (f32, f32) {
        (self.x[0], self.x[1])
    }

    /// Estimated heading bias of the odometry, degrees (true = odometry + bias).
    pub fn heading_bias_deg(&self) -> f32 {
        self.x[2].to_degrees()
    }

    /// Standard deviation of the heading bias, degrees.
    pub fn heading_bias_sigma_deg(&self) -> f32 {
        libm::sqrtf(self.p[2][2].max(0.0)).to_degrees()
    }

    /// Position covariance `[[xx, xy], [xy, yy]]`, square metres.
    pub fn position_covariance(&self) -> [[f32; 2]; 2] {
        [[self.p[0][0], self.p[0][1]], [self.p[1][0], self.p[1][1]]]
    }

    /// Standard deviation along the position ellipse's major axis, metres.
    pub fn sigma_major_m(&self) -> f32 {
        let (a, b, d) = (self.p[0][0], self.p[0][1], self.p[1][1]);
        let half_tr = 0.5 * (a + d);
        let disc = libm::sqrtf((0.25 * (a - d) * (a - d) + b * b).max(0.0));
        libm::sqrtf((half_tr + disc).max(0.0))
    }

    /// Radius around [`Fusion::position`] that the next fix must search, metres.
    pub fn search_radius_m(&self) -> f32 {
        let c = &self.cfg;
        // max/min, not `clamp` (which has a panic path for min > max; the settings are
        // validated so that min <= max).
        (c.radius_sigmas * self.sigma_major_m() + c.radius_margin_m)
            .max(c.radius_min_m)
            .min(c.radius_max_m)
    }

    /// Fixes folded in so far.
    pub fn accepted_count(&self) -> u32 {
        self.accepted
    }

    /// Fixes refused so far.
    pub fn rejected_count(&self) -> u32 {
        self.rejected
    }

    /// Refusals since the last accepted fix.
    pub fn rejection_streak(&self) -> u32 {
        self.streak
    }

    /// Carries the state over one odometry leg (module docs: the drift model).
    pub fn predict(&mut self, leg: &OdometryLeg) -> Result<(), FusionError> {
        let d = finite(leg.distance_m, "distance_m")?;
        if d < 0.0 {
            return Err(FusionError::NonFinite { what: "distance_m" });
        }
        let h = finite(leg.heading_deg, "heading_deg")?.to_radians() + self.x[2];
        let (s, c) = (libm::sinf(h), libm::cosf(h));
        // Motion: x += d sin h, y += d cos h. Jacobian F = I + column 2 (d cos h, -d sin h).
        let x = [self.x[0] + d * s, self.x[1] + d * c, self.x[2]];
        let f: M3 = [[1.0, 0.0, d * c], [0.0, 1.0, -d * s], [0.0, 0.0, 1.0]];
        let mut p = mul(&mul(&f, &self.p), &transpose(&f));
        // Process noise: along-track (s, c), cross-track (c, -s), bias walk.
        let cfg = &self.cfg;
        let along = (cfg.scale_sigma * d) * (cfg.scale_sigma * d);
        let cross = cfg.walk_m2_per_m * d;
        p[0][0] += along * s * s + cross * c * c;
        p[0][1] += along * s * c - cross * c * s;
        p[1][0] += along * s * c - cross * c * s;
        p[1][1] += along * c * c + cross * s * s;
        p[2][2] += cfg.bias_walk_rad2_per_m * d;
        symmetrize(&mut p);
        check_state(&x, &p)?;
        self.x = x;
        self.p = p;
        Ok(())
    }

    /// Folds in a fix (module docs: status, gate, Joseph update). A refused fix inflates
    /// the position covariance by [`FusionConfig::reject_inflation`].
    pub fn update(&mut self, fix: &FixReport) -> Result<UpdateOutcome, FusionError> {
        if fix.status != FixStatus::Ok {
            self.refuse();
            return Ok(UpdateOutcome {
                rejected: Some(RejectReason::Status(fix.status)),
                mahalanobis2: 0.0,
            });
        }
        let zx = finite(fix.x_m, "fix x_m")?;
        let zy = finite(fix.y_m, "fix y_m")?;
        let bound = finite(fix.error_bound_m, "fix error_bound_m")?;
        if bound <= 0.0 {
            return Err(FusionError::NonFinite {
                what: "fix error_bound_m",
            });
        }
        let sr = bound / self.cfg.bound_to_sigma;
        let r = sr * sr;
        let nu = [zx - self.x[0], zy - self.x[1]];
        let s = [
            [self.p[0][0] + r, self.p[0][1]],
            [self.p[1][0], self.p[1][1] + r],
        ];
        let det = s[0][0] * s[1][1] - s[0][1] * s[1][0];
        if !(det.is_finite() && det > 0.0) {
            return Err(FusionError::Degenerate);
        }
        let si = [
            [s[1][1] / det, -s[0][1] / det],
            [-s[1][0] / det, s[0][0] / det],
        ];
        let m2 = nu[0] * (si[0][0] * nu[0] + si[0][1] * nu[1])
            + nu[1] * (si[1][0] * nu[0] + si[1][1] * nu[1]);
        if !m2.is_finite() {
            return Err(FusionError::Degenerate);
        }
        if m2 > self.cfg.gate_chi2 {
            self.refuse();
            return Ok(UpdateOutcome {
                rejected: Some(RejectReason::Gate { mahalanobis2: m2 }),
                mahalanobis2: m2,
            });
        }
        // Gain K = P H' S^-1 (3 x 2), H = [I2 0].
        let mut k = [[0.0f32; 2]; 3];
        for (ki, pi) in k.iter_mut().zip(&self.p) {
            ki[0] = pi[0] * si[0][0] + pi[1] * si[1][0];
            ki[1] = pi[0] * si[0][1] + pi[1] * si[1][1];
        }
        let mut x = self.x;
        for (xi, ki) in x.iter_mut().zip(&k) {
            *xi += ki[0] * nu[0] + ki[1] * nu[1];
        }
        // Joseph form: (I - K H) P (I - K H)' + K R K'.
        let mut a: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        for (ai, ki) in a.iter_mut().zip(&k) {
            ai[0] -= ki[0];
            ai[1] -= ki[1];
        }
        let mut p = mul(&mul(&a, &self.p), &transpose(&a));
        for (i, pi) in p.iter_mut().enumerate() {
            for (j, pij) in pi.iter_mut().enumerate() {
                *pij += r * (k[i][0] * k[j][0] + k[i][1] * k[j][1]);
            }
        }
        symmetrize(&mut p);
        check_state(&x, &p)?;
        self.x = x;
        self.p = p;
        self.accepted = self.accepted.saturating_add(1);
        self.streak = 0;
        Ok(UpdateOutcome {
            rejected: None,
            mahalanobis2: m2,
        })
    }

    fn refuse(&mut self) {
        self.rejected = self.rejected.saturating_add(1);
        self.streak = self.streak.saturating_add(1);
        let f = self.cfg.reject_inflation;
        for row in self.p.iter_mut().take(2) {
            for v in row.iter_mut().take(2) {
                *v *= f;
            }
        }
    }
}

fn mul(a: &M3, b: &M3) -> M3 {
    let mut out = [[0.0f32; 3]; 3];
    for (oi, ai) in out.iter_mut().zip(a) {
        for (j, o) in oi.iter_mut().enumerate() {
            *o = ai[0] * b[0][j] + ai[1] * b[1][j] + ai[2] * b[2][j];
        }
    }
    out
}

fn transpose(a: &M3) -> M3 {
    [
        [a[0][0], a[1][0], a[2][0]],
        [a[0][1], a[1][1], a[2][1]],
        [a[0][2], a[1][2], a[2][2]],
    ]
}

fn symmetrize(p: &mut M3) {
    for (i, j) in [(0, 1), (0, 2), (1, 2)] {
        let m = 0.5 * (p[i][j] + p[j][i]);
        p[i][j] = m;
        p[j][i] = m;
    }
}

fn check_state(x: &[f32; 3], p: &M3) -> Result<(), FusionError> {
    if x.iter().any(|v| !v.is_finite()) || p.iter().flatten().any(|v| !v.is_finite()) {
        return Err(FusionError::Degenerate);
    }
    if p[0][0] <= 0.0 || p[1][1] <= 0.0 || p[2][2] < 0.0 {
        return Err(FusionError::Degenerate);
    }
    Ok(())
}
