//! The GeoKey directory of a GeoTIFF (GeoKeyDirectoryTag 34735 with GeoDoubleParamsTag 34736
//! and GeoAsciiParamsTag 34737) and the coordinate reference system it describes.
//!
//! Read: a projected CRS in metres, either an EPSG code (ProjectedCSTypeGeoKey) or a
//! user-defined one whose ProjLinearUnitsGeoKey is metre (9001); heights, when a vertical
//! unit is given, in metres. Refused: geographic (degrees) and geocentric models, other
//! linear units, files without GeoKeys.
//!
//! Written: the CRS orbfix gives its procedural world, IAU_2015:30110 "Moon (2015) - Sphere /
//! Ocentric / Equirectangular, clon = 0" (sphere of radius 1,737,400 m, true scale on the
//! equator): world `(x, y)` metres are its easting and northing, so a region near the world
//! origin lies on the lunar equator near longitude 0, where the projection's scale error is
//! below 10^-5 over the 8 km world. The keys are those GDAL 3.6 writes for that code.

use super::georef::RasterType;
use std::collections::BTreeMap;

/// TIFF tag: GeoKeyDirectoryTag.
pub const TAG_GEO_KEY_DIRECTORY: u16 = 34735;
/// TIFF tag: GeoDoubleParamsTag.
pub const TAG_GEO_DOUBLE_PARAMS: u16 = 34736;
/// TIFF tag: GeoAsciiParamsTag.
pub const TAG_GEO_ASCII_PARAMS: u16 = 34737;

const GT_MODEL_TYPE: u16 = 1024;
const GT_RASTER_TYPE: u16 = 1025;
const GT_CITATION: u16 = 1026;
const GEOG_ANGULAR_UNITS: u16 = 2054;
const PROJECTED_CS_TYPE: u16 = 3072;
const PCS_CITATION: u16 = 3073;
const PROJ_LINEAR_UNITS: u16 = 3076;
const VERTICAL_UNITS: u16 = 4099;

/// EPSG code of the metre (linear units).
const EPSG_METRE: u16 = 9001;
/// "User-defined" in GeoKeys.
const USER_DEFINED: u16 = 32767;

/// Name of the CRS orbfix writes (as GDAL's IAU_2015 database spells it).
pub const WORLD_CRS_NAME: &str = "Moon (2015) - Sphere / Ocentric / Equirectangular, clon = 0";
/// Authority code of the CRS orbfix writes.
pub const WORLD_CRS_CODE: &str = "IAU_2015:30110";
/// Radius of the IAU 2015 lunar sphere, metres.
pub const MOON_RADIUS_M: f64 = 1_737_400.0;

/// One GeoKey value.
#[derive(Clone, Debug, PartialEq)]
pub enum KeyValue {
    /// A SHORT stored in the directory.
    Short(u16),
    /// DOUBLEs from GeoDoubleParamsTag.
    Doubles(Vec<f64>),
    /// Text from GeoAsciiParamsTag (the trailing `|` removed).
    Ascii(String),
}

/// A parsed GeoKey directory.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GeoKeys {
    keys: BTreeMap<u16, KeyValue>,
}

impl GeoKeys {
    /// Parses the three GeoKey tags (the double and ASCII ones may be empty).
    pub fn parse(dir: &[u16], doubles: &[f64], ascii: &str) -> Result<Self, String> {
        let bad = |what: &str| format!("GeoKeyDirectoryTag is malformed: {what}");
        if dir.len() < 4 {
            return Err(bad("shorter than its 4-value header"));
        }
        if dir[0] != 1 {
            return Err(bad(&format!(
                "key directory version {} (expected 1)",
                dir[0]
            )));
        }
        let n = dir[3] as usize;
        if dir.len() < 4 + 4 * n {
            return Err(bad(&format!("{n} keys announced, {} values", dir.len())));
        }
        let mut keys = BTreeMap::new();
        for k in 0..n {
            let e = &dir[4 + 4 * k..8 + 4 * k];
            let (id, loc, count, off) = (e[0], e[1], e[2] as usize, e[3] as usize);
            let v = match loc {
                0 => KeyValue::Short(e[3]),
                TAG_GEO_DOUBLE_PARAMS => KeyValue::Doubles(
                    doubles
                        .get(off..off + count)
                        .ok_or_else(|| bad(&format!("key {id} points past the doubles")))?
                        .to_vec(),
                ),
                TAG_GEO_ASCII_PARAMS => {
                    let s = ascii
                        .get(off..off + count)
                        .ok_or_else(|| bad(&format!("key {id} points past the text")))?;
                    KeyValue::Ascii(s.trim_end_matches(['|', '\0']).to_string())
                }
                // Keys stored in other tags (e.g. in the directory itself): keep them out.
                _ => continue,
            };
            keys.insert(id, v);
        }
        Ok(Self { keys })
    }

    /// The SHORT value of a key, if present as a SHORT.
    pub fn short(&self, id: u16) -> Option<u16> {
        match self.keys.get(&id) {
            Some(KeyValue::Short(v)) => Some(*v),
            _ => None,
        }
    }

    /// The text of a key, if present as text.
    pub fn ascii(&self, id: u16) -> Option<&str> {
        match self.keys.get(&id) {
            Some(KeyValue::Ascii(s)) => Some(s.as_str()),
            _ => None,
        }
    }
}

/// A projected CRS in metres, as read from (or written to) a GeoTIFF.
#[derive(Clone, Debug, PartialEq)]
pub struct Crs {
    /// EPSG code of the projected CRS (ProjectedCSTypeGeoKey); `None` when user-defined.
    pub epsg: Option<u16>,
    /// Its name (PCSCitationGeoKey or GTCitationGeoKey), empty when none is given.
    pub name: String,
    /// What the raster coordinates of the georeference refer to.
    pub raster_type: RasterType,
}

impl Crs {
    /// The CRS orbfix writes for its procedural world ([`WORLD_CRS_CODE`]).
    pub fn world() -> Self {
        Self {
            epsg: None,
            name: WORLD_CRS_NAME.to_string(),
            raster_type: RasterType::PixelIsArea,
        }
    }

    /// The projected CRS in metres of a GeoKey directory, or why it is refused.
    pub fn from_keys(keys: &GeoKeys) -> Result<Self, String> {
        let supported = "orbfix reads projected CRSs in metres (GTModelTypeGeoKey = 1 with \
                         ProjLinearUnitsGeoKey = 9001, or a metric EPSG projected code)";
        match keys.short(GT_MODEL_TYPE) {
            Some(1) => {}
            Some(2) => {
                let unit = match keys.short(GEOG_ANGULAR_UNITS) {
                    Some(9102) | None => "degrees".to_string(),
                    Some(u) => format!("angular unit {u}"),
                };
                return Err(format!(
                    "the CRS is geographic (longitude/latitude in {unit}): {supported}; \
                     reproject with gdalwarp -t_srs (e.g. IAU_2015:30110 for the Moon, or \
                     the product's polar stereographic / equirectangular CRS)"
                ));
            }
            Some(3) => return Err(format!("the CRS is geocentric (x, y, z): {supported}")),
            Some(m) => return Err(format!("unknown GTModelTypeGeoKey {m}: {supported}")),
            None => {
                return Err(format!(
                    "the GeoKeys give no model type (GTModelTypeGeoKey): {supported}"
                ))
            }
        }
        let epsg = match keys.short(PROJECTED_CS_TYPE) {
            Some(USER_DEFINED) | None => None,
            Some(code) => Some(code),
        };
        match keys.short(PROJ_LINEAR_UNITS) {
            Some(EPSG_METRE) => {}
            Some(u) => {
                return Err(format!(
                    "the projected CRS has linear unit {u} (EPSG unit code), not metre \
                     (9001): {supported}; reproject with gdalwarp -t_srs to a metric CRS"
                ))
            }
            None => match epsg {
                Some(code) if epsg_is_metric(code) => {}
                Some(code) => {
                    return Err(format!(
                        "EPSG:{code} without ProjLinearUnitsGeoKey: orbfix cannot tell its \
                         unit; {supported} (UTM 326xx/327xx, 258xx, 269xx and polar \
                         stereographic 3031/3413/3995 are known to be metric)"
                    ))
                }
                None => {
                    return Err(format!(
                        "a user-defined projected CRS without ProjLinearUnitsGeoKey: \
                         {supported}"
                    ))
                }
            },
        }
        if let Some(u) = keys.short(VERTICAL_UNITS) {
            if u != EPSG_METRE {
                return Err(format!(
                    "heights are in unit {u} (VerticalUnitsGeoKey), not metre (9001): \
                     orbfix reads heights in metres; scale them with gdal_translate \
                     -scale or gdal_calc.py first"
                ));
            }
        }
        let raster_type = match keys.short(GT_RASTER_TYPE) {
            Some(1) | None => RasterType::PixelIsArea,
            Some(2) => RasterType::PixelIsPoint,
            Some(t) => {
                return Err(format!(
                    "unknown GTRasterTypeGeoKey {t} (1 = PixelIsArea, 2 = PixelIsPoint)"
                ))
            }
        };
        let name = keys
            .ascii(PCS_CITATION)
            .or_else(|| keys.ascii(GT_CITATION))
            .unwrap_or("")
            .to_string();
        Ok(Self {
            epsg,
            name,
            raster_type,
        })
    }

    /// A short description for messages: `EPSG:32633 (name)` or `user-defined (name)`.
    pub fn describe(&self) -> String {
        let code = match self.epsg {
            Some(c) => format!("EPSG:{c}"),
            None => "user-defined".to_string(),
        };
        if self.name.is_empty() {
            code
        } else {
            format!("{code} \"{}\"", self.name)
        }
    }

    /// Whether two rasters are in the same CRS (same EPSG code, or both user-defined with
    /// the same name).
    pub fn same_crs(&self, other: &Crs) -> bool {
        self.epsg == other.epsg && (self.epsg.is_some() || self.name == other.name)
    }
}

/// The three GeoKey tags of [`Crs::world`] (PixelIsArea): directory, doubles, text. The same
/// keys GDAL 3.6 writes for IAU_2015:30110 (`gdal_translate -a_srs IAU_2015:30110`).
pub fn world_crs_keys() -> (Vec<u16>, Vec<f64>, String) {
    const GEOG_CITATION_TEXT: &str = "GCS Name = Moon (2015) - Sphere / Ocentric|Datum = \
         Moon (2015) - Sphere|Ellipsoid = Moon (2015) - Sphere|Primem = Reference Meridian|";
    let gt_citation = format!("{WORLD_CRS_NAME}|");
    let ascii = format!("{gt_citation}{GEOG_CITATION_TEXT}");
    let a = TAG_GEO_ASCII_PARAMS;
    let d = TAG_GEO_DOUBLE_PARAMS;
    // Doubles: centre latitude, centre longitude, standard parallel, false easting, false
    // northing (all 0), semi-major and semi-minor axes, prime meridian longitude (0).
    let doubles = vec![0.0, 0.0, 0.0, 0.0, 0.0, MOON_RADIUS_M, MOON_RADIUS_M, 0.0];
    let keys: [[u16; 4]; 20] = [
        [GT_MODEL_TYPE, 0, 1, 1],
        [GT_RASTER_TYPE, 0, 1, 1],
        [GT_CITATION, a, gt_citation.len() as u16, 0],
        [2048, 0, 1, USER_DEFINED], // GeographicTypeGeoKey
        [
            2049, // GeogCitationGeoKey
            a,
            GEOG_CITATION_TEXT.len() as u16,
            gt_citation.len() as u16,
        ],
        [2050, 0, 1, USER_DEFINED],       // GeogGeodeticDatumGeoKey
        [GEOG_ANGULAR_UNITS, 0, 1, 9102], // degree
        [2056, 0, 1, USER_DEFINED],       // GeogEllipsoidGeoKey
        [2057, d, 1, 5],                  // GeogSemiMajorAxisGeoKey
        [2058, d, 1, 6],                  // GeogSemiMinorAxisGeoKey
        [2061, d, 1, 7],                  // GeogPrimeMeridianLongGeoKey
        [PROJECTED_CS_TYPE, 0, 1, USER_DEFINED],
        [3074, 0, 1, USER_DEFINED], // ProjectionGeoKey
        [3075, 0, 1, 17],           // ProjCoordTransGeoKey = CT_Equirectangular
        [PROJ_LINEAR_UNITS, 0, 1, EPSG_METRE],
        [3078, d, 1, 2], // ProjStdParallel1GeoKey
        [3082, d, 1, 3], // ProjFalseEastingGeoKey
        [3083, d, 1, 4], // ProjFalseNorthingGeoKey
        [3088, d, 1, 1], // ProjCenterLongGeoKey
        [3089, d, 1, 0], // ProjCenterLatGeoKey
    ];
    let mut dir = vec![1, 1, 0, keys.len() as u16];
    for k in keys {
        dir.extend_from_slice(&k);
    }
    (dir, doubles, ascii)
}

/// EPSG projected codes known to be in metres without a units key.
fn epsg_is_metric(code: u16) -> bool {
    matches!(code,
        32601..=32660 | 32701..=32760 // WGS 84 / UTM
        | 25828..=25838               // ETRS89 / UTM
        | 26901..=26923               // NAD83 / UTM
        | 3031 | 3413 | 3995 | 3976 | 3857)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn world_keys_parse_back() {
        let (dir, dbl, ascii) = world_crs_keys();
        let keys = GeoKeys::parse(&dir, &dbl, &ascii).unwrap();
        let crs = Crs::from_keys(&keys).unwrap();
        assert_eq!(crs, Crs::world());
        assert_eq!(keys.ascii(2049).unwrap().split('|').count(), 4);
        assert!(crs.same_crs(&Crs::world()));
    }

    fn keys(entries: &[[u16; 4]]) -> GeoKeys {
        let mut dir = vec![1, 1, 0, entries.len() as u16];
        for e in entries {
            dir.extend_from_slice(e);
        }
        GeoKeys::parse(&dir, &[], "").unwrap()
    }

    #[test]
    fn refusals_say_what_is_supported() {
        let geographic = keys(&[[GT_MODEL_TYPE, 0, 1, 2], [2048, 0, 1, 4326]]);
        let e = Crs::from_keys(&geographic).unwrap_err();
        assert!(e.contains("geographic") && e.contains("degrees") && e.contains("metres"));
        let feet = keys(&[[GT_MODEL_TYPE, 0, 1, 1], [PROJ_LINEAR_UNITS, 0, 1, 9002]]);
        assert!(Crs::from_keys(&feet).unwrap_err().contains("not metre"));
        let unknown = keys(&[[GT_MODEL_TYPE, 0, 1, 1], [PROJECTED_CS_TYPE, 0, 1, 2263]]);
        assert!(Crs::from_keys(&unknown)
            .unwrap_err()
            .contains("cannot tell its unit"));
        let utm = keys(&[
            [GT_MODEL_TYPE, 0, 1, 1],
            [GT_RASTER_TYPE, 0, 1, 2],
            [PROJECTED_CS_TYPE, 0, 1, 32633],
        ]);
        let c = Crs::from_keys(&utm).unwrap();
        assert_eq!(
            (c.epsg, c.raster_type),
            (Some(32633), RasterType::PixelIsPoint)
        );
        assert_eq!(c.describe(), "EPSG:32633");
        assert!(GeoKeys::parse(&[1, 1, 0, 3], &[], "").is_err());
    }
}
