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
//! - [`flight_run`]: the fix as one call with per-stage hooks (timed on target, re-run on host).
//! - [`nn`]: quantized siamese CNN matcher (int8 kernels, weight file, shipped network).
#![no_std]
#![deny(unsafe_op_in_unsafe_fn)]
#![warn(missing_docs)]
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]

pub mod camera;
pub mod flight_run;
pub mod geo;
pub mod image;
pub mod localize;
mod localize_messages;
pub mod matcher;
pub mod nn;
pub mod reproject;
pub mod scratch;
