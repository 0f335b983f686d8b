//! Raster-to-model georeference of a GeoTIFF: ModelPixelScaleTag (33550) + ModelTiepointTag
//! (33922), or ModelTransformationTag (34264) without rotation or shear; PixelIsArea or
//! PixelIsPoint (GTRasterTypeGeoKey). Only north-up rasters with square pixels map to the
//! core's [`GeoRef`]; the rest is refused with the reason.

use orbfix::geo::{GeoError, GeoRef};

/// TIFF tag: ModelPixelScaleTag, `(sx, sy, sz)` model units per pixel.
pub const TAG_MODEL_PIXEL_SCALE: u16 = 33550;
/// TIFF tag: ModelTiepointTag, `(i, j, k, x, y, z)` per tie point.
pub const TAG_MODEL_TIEPOINT: u16 = 33922;
/// TIFF tag: ModelTransformationTag, a row-major 4 x 4 raster-to-model matrix.
pub const TAG_MODEL_TRANSFORMATION: u16 = 34264;

/// Relative tolerance on "square pixels" and "no rotation" (the transform's off-diagonal
/// terms and the difference of the two pixel sizes, relative to the pixel size).
const REL_TOL: f64 = 1e-6;

/// What the raster coordinates of the tie point or transformation refer to
/// (GTRasterTypeGeoKey, 1025).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RasterType {
    /// `RasterPixelIsArea` (1, the default): raster `(0, 0)` is the north-west corner of the
    /// first pixel.
    PixelIsArea,
    /// `RasterPixelIsPoint` (2): raster `(0, 0)` is the centre of the first pixel.
    PixelIsPoint,
}

/// Georeference of a north-up raster in double precision: the model (CRS) coordinates of its
/// north-west corner, metres, and the ground size of a pixel, metres per pixel. Pixel
/// `(col, row)` has its centre at `(x0 + (col + 0.5) r, y0 - (row + 0.5) r)`
/// (`docs/frames.md`). Double precision because projected coordinates of real products
/// reach millions of metres, where the core's `f32` [`GeoRef`] keeps only decimetres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Georeference {
    origin_x_m: f64,
    origin_y_m: f64,
    m_per_px: f64,
}

impl Georeference {
    /// A checked georeference: finite origin, positive finite resolution.
    pub fn new(origin_x_m: f64, origin_y_m: f64, m_per_px: f64) -> Result<Self, String> {
        if !(m_per_px.is_finite() && m_per_px > 0.0) {
            return Err(format!(
                "pixel size {m_per_px} m must be positive and finite"
            ));
        }
        if !(origin_x_m.is_finite() && origin_y_m.is_finite()) {
            return Err(format!(
                "raster origin ({origin_x_m}, {origin_y_m}) m must be finite"
            ));
        }
        Ok(Self {
            origin_x_m,
            origin_y_m,
            m_per_px,
        })
    }

    /// The double-precision copy of a core georeference.
    pub fn from_georef(g: &GeoRef) -> Self {
        Self {
            origin_x_m: g.origin_x_m() as f64,
            origin_y_m: g.origin_y_m() as f64,
            m_per_px: g.m_per_px() as f64,
        }
    }

    /// The core's `f32` georeference (rounds to `f32`: keep coordinates below about
    /// 10^6 m for centimetre precision).
    pub fn to_georef(&self) -> Result<GeoRef, GeoError> {
        GeoRef::new(
            self.origin_x_m as f32,
            self.origin_y_m as f32,
            self.m_per_px as f32,
        )
    }

    /// Model `x` (east) of the raster's west edge, metres.
    pub fn origin_x_m(&self) -> f64 {
        self.origin_x_m
    }

    /// Model `y` (north) of the raster's north edge, metres.
    pub fn origin_y_m(&self) -> f64 {
        self.origin_y_m
    }

    /// Ground size of one pixel, metres per pixel.
    pub fn m_per_px(&self) -> f64 {
        self.m_per_px
    }

    /// Model coordinates (metres) of continuous pixel coordinates `(col, row)` (pixel
    /// centres at `+0.5`).
    pub fn to_model(&self, col: f64, row: f64) -> (f64, f64) {
        (
            self.origin_x_m + col * self.m_per_px,
            self.origin_y_m - row * self.m_per_px,
        )
    }

    /// Continuous pixel coordinates `(col, row)` of a model point (metres).
    pub fn to_pixel(&self, x_m: f64, y_m: f64) -> (f64, f64) {
        (
            (x_m - self.origin_x_m) / self.m_per_px,
            (self.origin_y_m - y_m) / self.m_per_px,
        )
    }

    /// `[west, south, east, north]` edges (metres) of a `width x height` raster.
    pub fn extent(&self, width: usize, height: usize) -> [f64; 4] {
        [
            self.origin_x_m,
            self.origin_y_m - height as f64 * self.m_per_px,
            self.origin_x_m + width as f64 * self.m_per_px,
            self.origin_y_m,
        ]
    }

    /// The georeference from the model tags of a GeoTIFF (as read, `None` when absent).
    /// Refuses rotation, shear, non-square or south-up pixels, several tie points without
    /// a scale (ground control points) and missing tags, saying what is supported.
    pub fn from_tags(
        pixel_scale: Option<&[f64]>,
        tiepoints: Option<&[f64]>,
        transformation: Option<&[f64]>,
        raster_type: RasterType,
    ) -> Result<Self, String> {
        let (mut x0, mut y0, r) = match (transformation, pixel_scale, tiepoints) {
            (Some(m), _, _) => {
                if m.len() != 16 {
                    return Err(format!(
                        "ModelTransformationTag has {} values, a 4 x 4 matrix has 16",
                        m.len()
                    ));
                }
                let (a, b, d, e, f, h) = (m[0], m[1], m[3], m[4], m[5], m[7]);
                let r = a;
                if !(r.is_finite() && r > 0.0 && f.is_finite() && f < 0.0) {
                    return Err(format!(
                        "ModelTransformationTag scales ({a}, {f}) are not north-up: orbfix \
                         reads north-up rasters (x growing east with the column, y growing \
                         north against the row); warp the file with gdalwarp first"
                    ));
                }
                if b.abs() > REL_TOL * r || e.abs() > REL_TOL * r {
                    return Err(format!(
                        "ModelTransformationTag has rotation or shear terms ({b}, {e}): \
                         orbfix reads north-up rasters only; warp the file with gdalwarp \
                         (e.g. gdalwarp -t_srs <same CRS> in.tif out.tif) first"
                    ));
                }
                check_square(r, -f)?;
                (d, h, r)
            }
            (None, Some(s), Some(t)) => {
                if s.len() < 2 {
                    return Err(format!(
                        "ModelPixelScaleTag has {} values, expected (sx, sy, sz)",
                        s.len()
                    ));
                }
                if t.len() != 6 {
                    return Err(format!(
                        "ModelTiepointTag has {} values: orbfix reads one tie point \
                         (6 values) with a pixel scale; ground control points need \
                         gdalwarp first",
                        t.len()
                    ));
                }
                let (sx, sy) = (s[0], s[1]);
                if !(sx.is_finite() && sx > 0.0 && sy.is_finite() && sy > 0.0) {
                    return Err(format!(
                        "ModelPixelScaleTag ({sx}, {sy}) must be positive and finite \
                         (a north-up raster)"
                    ));
                }
                check_square(sx, sy)?;
                let (i, j, x, y) = (t[0], t[1], t[3], t[4]);
                (x - i * sx, y + j * sx, sx)
            }
            (None, None, Some(_)) => {
                return Err("the file has tie points but no ModelPixelScaleTag (ground \
                     control points): orbfix reads a pixel scale + one tie point or a \
                     transformation; georectify with gdalwarp first"
                    .into())
            }
            _ => {
                return Err(
                    "the file has no georeference (neither ModelPixelScaleTag + \
                     ModelTiepointTag nor ModelTransformationTag): assign one with \
                     gdal_translate -a_ullr / -a_srs"
                        .into(),
                )
            }
        };
        if raster_type == RasterType::PixelIsPoint {
            // Raster (0, 0) is the first pixel's centre: the corner is half a pixel out.
            x0 -= 0.5 * r;
            y0 += 0.5 * r;
        }
        Self::new(x0, y0, r)
    }

    /// `(ModelPixelScaleTag, ModelTiepointTag)` of this georeference, PixelIsArea: raster
    /// `(0, 0)` is tied to the north-west corner.
    pub fn to_tags(&self) -> ([f64; 3], [f64; 6]) {
        (
            [self.m_per_px, self.m_per_px, 0.0],
            [0.0, 0.0, 0.0, self.origin_x_m, self.origin_y_m, 0.0],
        )
    }
}

fn check_square(sx: f64, sy: f64) -> Result<(), String> {
    if (sx - sy).abs() > REL_TOL * sx {
        return Err(format!(
            "pixels are {sx} x {sy} model units, not square: orbfix needs square pixels; \
             resample with gdalwarp -tr R R first"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiepoint_scale_area_and_point() {
        let s = [0.5, 0.5, 0.0];
        let t = [2.0, 4.0, 0.0, 1000.0, 2000.0, 0.0];
        let g = Georeference::from_tags(Some(&s), Some(&t), None, RasterType::PixelIsArea).unwrap();
        assert_eq!(
            (g.origin_x_m(), g.origin_y_m(), g.m_per_px()),
            (999.0, 2002.0, 0.5)
        );
        let p =
            Georeference::from_tags(Some(&s), Some(&t), None, RasterType::PixelIsPoint).unwrap();
        assert_eq!((p.origin_x_m(), p.origin_y_m()), (998.75, 2002.25));
        // The centre of pixel (2, 4) is the tie point's model point for PixelIsPoint.
        assert_eq!(p.to_model(2.5, 4.5), (1000.0, 2000.0));
    }

    #[test]
    fn transformation_and_refusals() {
        let m = [
            2.0, 0.0, 0.0, 10.0, 0.0, -2.0, 0.0, 20.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
        ];
        let g = Georeference::from_tags(None, None, Some(&m), RasterType::PixelIsArea).unwrap();
        assert_eq!(
            (g.origin_x_m(), g.origin_y_m(), g.m_per_px()),
            (10.0, 20.0, 2.0)
        );
        let mut rot = m;
        rot[1] = 0.1;
        let e = Georeference::from_tags(None, None, Some(&rot), RasterType::PixelIsArea);
        assert!(e.unwrap_err().contains("rotation"));
        let e = Georeference::from_tags(
            Some(&[1.0, 2.0, 0.0]),
            Some(&[0.0; 6]),
            None,
            RasterType::PixelIsArea,
        );
        assert!(e.unwrap_err().contains("not square"));
        let e = Georeference::from_tags(None, None, None, RasterType::PixelIsArea);
        assert!(e.unwrap_err().contains("no georeference"));
        let e = Georeference::from_tags(
            Some(&[1.0, 1.0, 0.0]),
            Some(&[0.0; 12]),
            None,
            RasterType::PixelIsArea,
        );
        assert!(e.unwrap_err().contains("one tie point"));
    }

    #[test]
    fn tags_round_trip() {
        let g = Georeference::new(-1234.5, 6789.25, 0.25).unwrap();
        let (s, t) = g.to_tags();
        let back =
            Georeference::from_tags(Some(&s), Some(&t), None, RasterType::PixelIsArea).unwrap();
        assert_eq!(back, g);
        assert_eq!(g.extent(4, 8), [-1234.5, 6787.25, -1233.5, 6789.25]);
    }
}
