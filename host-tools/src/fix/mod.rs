//! The host's harness around the core's one fix ([`orbfix::fix::run`]): building map
//! products from rendered map regions ([`product`]) and running the fix on owned images with
//! owned scratch ([`runner`], [`scratch`]). Nothing here is a stage of the fix.

pub mod product;
pub mod runner;
pub mod scratch;

pub use product::{build_map_product, build_map_product_relief, Heights, MapProductOptions};
pub use runner::{FixDepth, FixOutcome, FixRunner};
pub use scratch::OwnedScratch;
