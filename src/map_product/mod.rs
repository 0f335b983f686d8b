//! The map product (`.ofm`, "orbfix map"): the one file the rover carries for a region, made
//! on the ground by `orbfix map` and validated here before any use.
//!
//! It holds the orbital map pixels (north-up, u8), their georeference, the refinement plane
//! (the map high-passed and rectified as the fix's refinement needs it, made once on the
//! ground instead of around every candidate on board: [`write_refine_plane`]), and the CNN
//! records of the map windows ([`crate::nn::window_cosine`]: 50 m windows on a grid, each an
//! int8 embedding with its sums), with the settings they were made with and a CRC-32 trailer.
//!
//! Layout (little-endian; `docs/map-format.md`):
//!
//! | offset | bytes | field |
//! |---:|---:|---|
//! | 0 | 4 | magic `OFM1` |
//! | 4 | 2 | version (3; version 2 files, without relief, are still read) |
//! | 6 | 2 | relief block side, pixels (0: no relief plane; else the window grid step) |
//! | 8 | 4 | header bytes ([`HEADER_BYTES`] = 64) |
//! | 12 | 4 | map width, pixels |
//! | 16 | 4 | map height, pixels |
//! | 20 | 4 | `f32` world east of the west edge, metres |
//! | 24 | 4 | `f32` world north of the north edge, metres |
//! | 28 | 4 | `f32` metres per pixel |
//! | 32 | 4 | window side, pixels (the top-down grid's `n`) |
//! | 36 | 4 | window grid step, pixels |
//! | 40 | 4 | window grid columns |
//! | 44 | 4 | window grid rows |
//! | 48 | 4 | CRC-32 of the weight file the records were computed with |
//! | 52 | 4 | `f32` sun elevation of the orbital image, degrees (NaN: unknown) |
//! | 56 | 4 | `f32` sun azimuth of the orbital image, degrees clockwise from north (NaN: unknown) |
//! | 60 | 2 | refinement plane: high-pass box radius, pixels (1-1024) |
//! | 62 | 1 | refinement plane: 1 rectified (`2 abs(v - 128)`), 0 signed |
//! | 63 | 1 | reserved, 0 |
//! | 64 | w h | map pixels, row-major, row 0 north |
//! | 64 + w h | w h | refinement plane, row-major ([`write_refine_plane`]) |
//! | | 0-3 | zero padding to a multiple of 4 |
//! | | cols rows 2056 | window records, row-major over the grid (top-left of window `(c, r)` at map pixel `(c step, r step)`) |
//! | | rc rr 2 | relief plane, if any: `i16` heights, Q4 metres (1/16 m) above any datum, row-major, row 0 north ([`ReliefPlane`]) |
//! | end - 4 | 4 | CRC-32 (IEEE) of every preceding byte |
//!
//! The relief plane is the elevation model on blocks of `b` pixels (`b`: the window step):
//! block `(i, j)` covers map pixels `o + i b .. o + (i + 1) b` east and the same south, with
//! `o = (n - nb b) / 2` and `nb = n / b` blocks per window side (`n`: the window side), so
//! the blocks of the window at grid cell `(c, r)` are `(c .. c + nb, r .. r + nb)` and the
//! plane has `rc = cols + nb - 1` columns and `rr = rows + nb - 1` rows. The fix matches it
//! against the relief its range reprojection saw ([`crate::reproject::ReliefGrid`]).
//!
//! [`MapProduct::parse`] checks the CRC first (a damaged file is reported as damaged, not as
//! whatever its damaged header claims), then every field and that the sizes agree.

mod write;

pub use write::{
    refine_plane_buffer_len, seal, write_header, write_refine_plane, write_window_records,
};

use crate::geo::GeoRef;
use crate::image::ImageView;
use crate::nn::weights::crc32;
use crate::nn::window_cosine::WINDOW_RECORD_BYTES;
use core::fmt;

/// File magic.
pub const MAGIC: [u8; 4] = *b"OFM1";
/// Format version this core writes (it reads this one and version 2, which has no relief).
pub const VERSION: u16 = 3;
/// Fractional bits of the relief plane's heights: Q4 metres.
pub const RELIEF_PLANE_FRAC_BITS: u32 = 4;
/// Bytes of the header.
pub const HEADER_BYTES: usize = 64;
/// Largest map side the core accepts, pixels (16,384 px: 4.1 km at 0.25 m/px).
pub const MAX_SIDE_PX: usize = 16_384;
/// Largest high-pass radius of the refinement plane, pixels.
pub const MAX_PLANE_RADIUS_PX: usize = 1024;
/// Largest distance of the map origin from the world origin, metres (10,000 km: more than
/// any planetary radius the rover could work on).
pub const MAX_ORIGIN_M: f32 = 1.0e7;

/// Why a map product was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MapProductError {
    /// Shorter than a header and a CRC.
    Truncated {
        /// Bytes present.
        got: usize,
    },
    /// The stored CRC-32 differs from the content's: the file is damaged.
    CrcMismatch {
        /// CRC in the trailer.
        stored: u32,
        /// CRC of the content.
        computed: u32,
    },
    /// Not a map product.
    BadMagic,
    /// A version this core cannot read.
    UnsupportedVersion(u16),
    /// A header field is out of range (`field` names it).
    BadField {
        /// The field.
        field: &'static str,
    },
    /// The file's length differs from what its header declares.
    LengthMismatch {
        /// Bytes the header declares.
        expected: usize,
        /// Bytes present.
        got: usize,
    },
    /// The output buffer of a writer is too small.
    BufferTooSmall {
        /// Bytes needed.
        needed: usize,
    },
}

impl fmt::Display for MapProductError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Truncated { got } => write!(
                f,
                "the map product is truncated ({got} bytes, less than a header and a checksum); copy it again"
            ),
            Self::CrcMismatch { stored, computed } => write!(
                f,
                "the map product is damaged (CRC-32 {computed:#010x}, the file says {stored:#010x}); copy it again or rebuild it with `orbfix map`"
            ),
            Self::BadMagic => write!(f, "not an orbfix map product (no OFM1 magic); build one with `orbfix map`"),
            Self::UnsupportedVersion(v) => write!(
                f,
                "map product version {v} is not supported (this core reads version {VERSION}); rebuild it with this version's `orbfix map`"
            ),
            Self::BadField { field } => write!(
                f,
                "the map product's header field '{field}' is out of range; rebuild it with `orbfix map`"
            ),
            Self::LengthMismatch { expected, got } => write!(
                f,
                "the map product is {got} bytes but its header declares {expected}; copy it again"
            ),
            Self::BufferTooSmall { needed } => {
                write!(f, "the map product buffer is too small ({needed} bytes needed)")
            }
        }
    }
}

impl core::error::Error for MapProductError {}

/// How the refinement plane of a map product was made: the box radius and the rectification
/// of the high-pass ([`crate::matcher::prep`]). The fix refuses a product whose plane was
/// made with other settings than its own (`FixConfig::refine_plane`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RefinePlane {
    radius_px: u16,
    rectify: bool,
}

impl RefinePlane {
    /// A plane with box radius `radius_px` pixels (1 to [`MAX_PLANE_RADIUS_PX`]), rectified
    /// or signed.
    pub fn new(radius_px: usize, rectify: bool) -> Result<Self, MapProductError> {
        if !(1..=MAX_PLANE_RADIUS_PX).contains(&radius_px) {
            return Err(MapProductError::BadField {
                field: "refinement plane radius",
            });
        }
        Ok(Self {
            radius_px: radius_px as u16,
            rectify,
        })
    }

    /// Box radius of the high-pass, map pixels.
    pub fn radius_px(&self) -> usize {
        self.radius_px as usize
    }

    /// Whether the high-pass is rectified.
    pub fn rectify(&self) -> bool {
        self.rectify
    }
}

/// What a map product describes besides its pixels and records.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MapProductMeta {
    /// Georeference of the map pixels.
    pub geo: GeoRef,
    /// Map width, pixels.
    pub width: usize,
    /// Map height, pixels.
    pub height: usize,
    /// Window side, pixels (the top-down grid's `n`).
    pub window_px: usize,
    /// Window grid step, pixels.
    pub step_px: usize,
    /// CRC-32 of the weight file the records were made with.
    pub weights_crc: u32,
    /// Sun of the orbital image `(elevation, azimuth)`, degrees, if known.
    pub sun_deg: Option<(f32, f32)>,
    /// How the refinement plane was made.
    pub plane: RefinePlane,
    /// Block side of the relief plane, pixels: 0 for none, else the window step, a power
    /// of two from 2 to [`crate::reproject::MAX_BLOCK_PX`] with at least two blocks per
    /// window side.
    pub relief_block_px: usize,
}

/// Offsets and sizes of a map product's parts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MapProductLayout {
    /// Window grid columns.
    pub cols: usize,
    /// Window grid rows.
    pub rows: usize,
    /// Offset of the pixels (= [`HEADER_BYTES`]).
    pub pixels_at: usize,
    /// Offset of the refinement plane (right after the pixels).
    pub plane_at: usize,
    /// Offset of the first window record (4-byte aligned).
    pub records_at: usize,
    /// Offset of the relief plane (right after the records; the CRC's offset when there is
    /// none).
    pub relief_at: usize,
    /// Relief plane columns and rows (0 when there is none).
    pub relief_cols: usize,
    /// Relief plane rows.
    pub relief_rows: usize,
    /// Relief blocks per window side (0 when there is none).
    pub relief_blocks: usize,
    /// Bytes of the whole file, CRC included.
    pub total: usize,
}

impl MapProductLayout {
    /// The layout of a `width x height` map with `window_px` windows every `step_px`, no
    /// relief plane.
    pub fn new(
        width: usize,
        height: usize,
        window_px: usize,
        step_px: usize,
    ) -> Result<Self, MapProductError> {
        Self::with_relief(width, height, window_px, step_px, 0)
    }

    /// The layout of the product `meta` describes.
    pub fn of(meta: &MapProductMeta) -> Result<Self, MapProductError> {
        Self::with_relief(
            meta.width,
            meta.height,
            meta.window_px,
            meta.step_px,
            meta.relief_block_px,
        )
    }

    /// [`MapProductLayout::new`] with a relief plane of `relief_block_px` blocks (0: none;
    /// else the window step, see [`MapProductMeta::relief_block_px`]).
    pub fn with_relief(
        width: usize,
        height: usize,
        window_px: usize,
        step_px: usize,
        relief_block_px: usize,
    ) -> Result<Self, MapProductError> {
        let bad = |field| MapProductError::BadField { field };
        if width == 0 || width > MAX_SIDE_PX {
            return Err(bad("width"));
        }
        if height == 0 || height > MAX_SIDE_PX {
            return Err(bad("height"));
        }
        if window_px == 0 || window_px > width || window_px > height {
            return Err(bad("window side"));
        }
        if step_px == 0 || step_px > window_px {
            return Err(bad("window step"));
        }
        let cols = (width - window_px) / step_px + 1;
        let rows = (height - window_px) / step_px + 1;
        // Sides are at most 2^14, so these products stay far below usize::MAX even on
        // 32-bit targets (2^28 pixels, 2^28 windows x 2056 bytes would not: checked).
        let pixels = width * height;
        let plane_at = HEADER_BYTES + pixels;
        let records_at = (plane_at + pixels).next_multiple_of(4);
        let records = (cols * rows)
            .checked_mul(WINDOW_RECORD_BYTES)
            .ok_or(bad("window grid"))?;
        let relief_at = records_at.checked_add(records).ok_or(bad("window grid"))?;
        let (relief_blocks, relief_cols, relief_rows) = if relief_block_px == 0 {
            (0, 0, 0)
        } else {
            if relief_block_px != step_px
                || crate::reproject::ReliefGrid::new(window_px, relief_block_px).is_err()
            {
                return Err(bad("relief block side"));
            }
            let nb = window_px / relief_block_px;
            (nb, cols + nb - 1, rows + nb - 1)
        };
        let total = (relief_cols * relief_rows)
            .checked_mul(2)
            .and_then(|r| r.checked_add(relief_at))
            .and_then(|t| t.checked_add(4))
            .ok_or(bad("window grid"))?;
        Ok(Self {
            cols,
            rows,
            pixels_at: HEADER_BYTES,
            plane_at,
            records_at,
            relief_at,
            relief_cols,
            relief_rows,
            relief_blocks,
            total,
        })
    }

    /// Windows on the grid.
    pub fn windows(&self) -> usize {
        self.cols * self.rows
    }
}

/// A validated map product, borrowing the file's bytes.
#[derive(Clone, Copy, Debug)]
pub struct MapProduct<'a> {
    meta: MapProductMeta,
    layout: MapProductLayout,
    map: ImageView<'a>,
    plane: ImageView<'a>,
    records: &'a [u8],
    relief: Option<ReliefPlane<'a>>,
}

/// The relief plane of a map product ([`MapProduct::relief`]): `i16` heights, Q4 metres
/// ([`RELIEF_PLANE_FRAC_BITS`]), on the window grid's blocks (module docs).
#[derive(Clone, Copy, Debug)]
pub struct ReliefPlane<'a> {
    bytes: &'a [u8],
    cols: usize,
    rows: usize,
    blocks: usize,
}

impl<'a> ReliefPlane<'a> {
    /// Columns (blocks east).
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Rows (blocks south).
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Blocks per window side.
    pub fn blocks(&self) -> usize {
        self.blocks
    }

    /// Height of block `(col, row)`, Q4 metres, or `None` outside the plane.
    #[inline(always)]
    pub fn get(&self, col: usize, row: usize) -> Option<i16> {
        if col >= self.cols {
            return None;
        }
        let at = 2 * (row * self.cols + col);
        match self.bytes.get(at..at + 2) {
            Some(&[a, b]) => Some(i16::from_le_bytes([a, b])),
            _ => None,
        }
    }

    /// Height of block `k` in row-major order (`row cols + col`), Q4 metres, or `None`
    /// past the end.
    #[inline(always)]
    pub fn at(&self, k: usize) -> Option<i16> {
        match self.bytes.get(2 * k..2 * k + 2) {
            Some(&[a, b]) => Some(i16::from_le_bytes([a, b])),
            _ => None,
        }
    }

    /// Blocks in the plane (`cols rows`).
    pub fn len(&self) -> usize {
        self.bytes.len() / 2
    }

    /// Whether the plane has no blocks.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The plane as `i16` in place, where the bytes are 2-aligned (on a little-endian
    /// target the stored order is the native one); `None` otherwise.
    #[cfg(target_endian = "little")]
    pub fn as_i16(&self) -> Option<&'a [i16]> {
        // Safety: every bit pattern is a valid `i16`; `align_to` only yields the aligned
        // middle part, which is used only when it is the whole plane.
        let (head, mid, tail) = unsafe { self.bytes.align_to::<i16>() };
        (head.is_empty() && tail.is_empty()).then_some(mid)
    }
}

/// Whether [`MapProduct::parse`] recomputes the CRC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CrcCheck {
    /// Recompute the CRC-32 of the whole file (about 10 instructions per byte on the
    /// target; once when the file is loaded, and in the fix's self-check).
    Verify,
    /// Trust a CRC verified earlier (structure still checked).
    Skip,
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    match b.get(at..at + 2) {
        Some(&[x, y]) => u16::from_le_bytes([x, y]),
        _ => 0,
    }
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    match b.get(at..at + 4) {
        Some(&[a, c, d, e]) => u32::from_le_bytes([a, c, d, e]),
        _ => 0,
    }
}

fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_bits(u32_at(b, at))
}

impl<'a> MapProduct<'a> {
    /// Validates `bytes` as a map product: CRC (unless `crc` is [`CrcCheck::Skip`]), magic,
    /// version, every header field, and the length.
    pub fn parse(bytes: &'a [u8], crc: CrcCheck) -> Result<Self, MapProductError> {
        if bytes.len() < HEADER_BYTES + 4 {
            return Err(MapProductError::Truncated { got: bytes.len() });
        }
        let body_len = bytes.len() - 4;
        if crc == CrcCheck::Verify {
            let stored = u32_at(bytes, body_len);
            let computed = crc32(bytes.get(..body_len).unwrap_or_default());
            if stored != computed {
                return Err(MapProductError::CrcMismatch { stored, computed });
            }
        }
        if bytes.get(..4) != Some(&MAGIC[..]) {
            return Err(MapProductError::BadMagic);
        }
        let version = u16_at(bytes, 4);
        if version != VERSION && version != 2 {
            return Err(MapProductError::UnsupportedVersion(version));
        }
        let relief_block_px = u16_at(bytes, 6) as usize;
        if version == 2 && relief_block_px != 0 {
            return Err(MapProductError::BadField {
                field: "relief block side",
            });
        }
        let bad = |field| MapProductError::BadField { field };
        if u32_at(bytes, 8) as usize != HEADER_BYTES {
            return Err(bad("header bytes"));
        }
        let (ox, oy, res) = (f32_at(bytes, 20), f32_at(bytes, 24), f32_at(bytes, 28));
        if !(ox.is_finite()
            && oy.is_finite()
            && ox.abs() <= MAX_ORIGIN_M
            && oy.abs() <= MAX_ORIGIN_M)
        {
            return Err(bad("origin"));
        }
        let geo = GeoRef::new(ox, oy, res).map_err(|_| bad("metres per pixel"))?;
        let width = u32_at(bytes, 12) as usize;
        let height = u32_at(bytes, 16) as usize;
        let window_px = u32_at(bytes, 32) as usize;
        let step_px = u32_at(bytes, 36) as usize;
        let layout =
            MapProductLayout::with_relief(width, height, window_px, step_px, relief_block_px)?;
        if u32_at(bytes, 40) as usize != layout.cols {
            return Err(bad("window columns"));
        }
        if u32_at(bytes, 44) as usize != layout.rows {
            return Err(bad("window rows"));
        }
        if bytes.len() != layout.total {
            return Err(MapProductError::LengthMismatch {
                expected: layout.total,
                got: bytes.len(),
            });
        }
        if bytes.get(62).is_some_and(|&r| r > 1) || bytes.get(63) != Some(&0) {
            return Err(bad("refinement plane rectification"));
        }
        let plane_settings =
            RefinePlane::new(u16_at(bytes, 60) as usize, bytes.get(62) == Some(&1))?;
        let (el, az) = (f32_at(bytes, 52), f32_at(bytes, 56));
        let sun_deg = if el.is_finite() && az.is_finite() {
            if !(-90.0..=90.0).contains(&el) {
                return Err(bad("sun elevation"));
            }
            Some((el, az))
        } else {
            None
        };
        let pixels = bytes
            .get(layout.pixels_at..layout.pixels_at + width * height)
            .ok_or(MapProductError::LengthMismatch {
                expected: layout.total,
                got: bytes.len(),
            })?;
        let plane_px = bytes
            .get(layout.plane_at..layout.plane_at + width * height)
            .ok_or(MapProductError::LengthMismatch {
                expected: layout.total,
                got: bytes.len(),
            })?;
        let relief = if layout.relief_blocks > 0 {
            Some(ReliefPlane {
                bytes: bytes.get(layout.relief_at..layout.total - 4).ok_or(
                    MapProductError::LengthMismatch {
                        expected: layout.total,
                        got: bytes.len(),
                    },
                )?,
                cols: layout.relief_cols,
                rows: layout.relief_rows,
                blocks: layout.relief_blocks,
            })
        } else {
            None
        };
        let records = bytes.get(layout.records_at..layout.relief_at).ok_or(
            MapProductError::LengthMismatch {
                expected: layout.total,
                got: bytes.len(),
            },
        )?;
        let map = ImageView::new(pixels, width, height).map_err(|_| bad("width"))?;
        let plane = ImageView::new(plane_px, width, height).map_err(|_| bad("width"))?;
        Ok(Self {
            meta: MapProductMeta {
                geo,
                width,
                height,
                window_px,
                step_px,
                weights_crc: u32_at(bytes, 48),
                sun_deg,
                plane: plane_settings,
                relief_block_px,
            },
            layout,
            map,
            plane,
            records,
            relief,
        })
    }

    /// Header values.
    pub fn meta(&self) -> &MapProductMeta {
        &self.meta
    }

    /// Offsets and the window grid.
    pub fn layout(&self) -> &MapProductLayout {
        &self.layout
    }

    /// The map pixels as an image.
    pub fn map(&self) -> ImageView<'a> {
        self.map
    }

    /// The refinement plane (the map high-passed as [`MapProductMeta::plane`] says), an
    /// image of the map's size.
    pub fn plane(&self) -> ImageView<'a> {
        self.plane
    }

    /// All window records, row-major over the grid.
    pub fn records(&self) -> &'a [u8] {
        self.records
    }

    /// The relief plane, if the product has one.
    pub fn relief(&self) -> Option<ReliefPlane<'a>> {
        self.relief
    }
}

#[cfg(test)]
mod tests;
