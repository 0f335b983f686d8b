//! # orbfix flight core
//!
//! Absolute position fix for a planetary rover from its own four ground views and an
//! orbital map, in `no_std` with no heap: every buffer is caller-provided or static with a
//! size known at compile time.
//!
//! Frames and units are fixed once for the whole project (see `docs/frames.md`):
//! - world: `x` east, `y` north, `z` up, metres;
//! - heading: degrees clockwise from north (0 = facing north, 90 = facing east);
//! - rasters: north-up, row 0 at the north edge, column 0 at the west edge, pixel
//!   `(col, row)` covering `[col, col + 1) x [row, row + 1)`, its centre at `+0.5`.
//!
//! Modules, one concept each:
//! - [`image`]: borrowed 8-bit grayscale image views;
//! - [`geo`]: georeference of north-up rasters;
//! - [`camera`]: pinhole camera model of the rover's four views;
//! - [`reproject`]: integer lookup-table reprojection of the four views to a top-down grid;
//! - [`matcher`]: L1, L2 and masked NCC scoring of a top-down image against map windows;
//! - [`localize`]: the study's 441-window search and the coarse-to-fine dense fix;
//! - [`fix`]: the one pipeline, four frames and a map product to a position with an error
//!   bound and a confidence (what flies, what is evaluated and what is budgeted);
//! - [`fusion`]: the fixes fused with odometry over a drive (a small Kalman filter with an
//!   innovation gate) and the next stop's search radius;
//! - [`map_product`]: the versioned map file the rover carries (map, georeference, CNN
//!   window records, CRC-32);
//! - [`peak`]: sub-sample peak location;
//! - [`nn`]: quantized siamese CNN matcher (int8 kernels, weight file, shipped network).
//! - [`peak`]: sub-sample refinement of extrema (parabola through three samples);
//! - [`stereo`]: depth from the rover's rectified stereo pairs, integer block matching in row
//!   bands.
#![no_std]
#![deny(unsafe_op_in_unsafe_fn)]
#![warn(missing_docs)]
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]

pub mod camera;
pub mod fix;
pub mod fusion;
pub mod geo;
pub mod image;
pub mod localize;
mod localize_messages;
pub mod map_product;
pub mod matcher;
pub mod nn;
pub mod peak;
pub mod reproject;
pub mod scratch;
pub mod stereo;
