//! Host-side reprojection tools: the f64 reference the core's integer paths are checked
//! against, the depth images the eval feeds the range path (the renderer's truth, optionally
//! with stereo-like noise), and the speed benchmark of the core's reprojection.

pub mod bench;
pub mod depth;
pub mod reference;
