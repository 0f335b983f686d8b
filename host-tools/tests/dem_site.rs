//! A DEM + orthoimage site (GeoTIFFs written by orbfix's writer, terrain not from the
//! procedural generator) through the one fix: the map is the orthoimage itself, the rover's
//! views are rendered over the DEM with the orthoimage as albedo, and `orbfix::fix::run`
//! places two stops within 1 m. Small enough for CI (a 160 m site, a 100 m map).

use orbfix::fix::{FixConfig, FixPath, FixStatus};
use orbfix_host::eval::pipeline::{map_region, PipelineOptions, Reprojection};
use orbfix_host::fix::FixRunner;
use orbfix_host::geotiff::{write_dem_f32, write_ortho_u8, Georeference};
use orbfix_host::render::{RenderOptions, Sun};
use orbfix_host::world::dem::MapSource;
use orbfix_host::world::World;
use rand::{Rng, SeedableRng};

mod common;
use common::{stop_on, Stop};

/// Site: 160 x 160 m, north-west corner (1000, 2160) m; DEM at 0.5 m, orthoimage at 0.25 m.
const WEST: f64 = 1000.0;
const NORTH: f64 = 2160.0;
const SIDE_M: f64 = 160.0;

/// Box blur (radius `r` pixels, clamped edges) of a square `n x n` field, rows then columns.
fn blur(v: &[f32], n: usize, r: usize) -> Vec<f32> {
    let pass = |src: &[f32], horizontal: bool| -> Vec<f32> {
        let mut out = vec![0f32; n * n];
        for a in 0..n {
            for b in 0..n {
                let (lo, hi) = (b.saturating_sub(r), (b + r).min(n - 1));
                let mut s = 0f32;
                for k in lo..=hi {
                    s += if horizontal {
                        src[a * n + k]
                    } else {
                        src[k * n + a]
                    };
                }
                let i = if horizontal { a * n + b } else { b * n + a };
                out[i] = s / (hi - lo + 1) as f32;
            }
        }
        out
    };
    pass(&pass(v, true), false)
}

/// Writes the site's DEM and orthoimage into `dir`: craters and blurred noise for relief,
/// multi-scale blurred noise for the gray levels, darker crater floors.
fn write_site(dir: &std::path::Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let no = (SIDE_M / 0.25) as usize;
    let nd = no / 2;
    let craters: Vec<(f64, f64, f64)> = (0..40)
        .map(|_| {
            (
                WEST + rng.random_range(0.0..SIDE_M),
                NORTH - rng.random_range(0.0..SIDE_M),
                rng.random_range(1.5..8.0),
            )
        })
        .collect();
    let crater_h = |x: f64, y: f64| -> f64 {
        craters
            .iter()
            .map(|&(cx, cy, r)| {
                let q = (x - cx).hypot(y - cy) / r;
                if q < 1.0 {
                    0.4 * r * (q * q - 1.0) + 0.08 * r
                } else {
                    0.08 * r * q.powi(-3)
                }
            })
            .sum()
    };
    let noise: Vec<f32> = (0..nd * nd).map(|_| rng.random_range(-1.0..1.0)).collect();
    let rough = blur(&noise, nd, 6);
    let dem: Vec<f32> = (0..nd * nd)
        .map(|i| {
            let (c, r) = (i % nd, i / nd);
            let (x, y) = (
                WEST + (c as f64 + 0.5) * 0.5,
                NORTH - (r as f64 + 0.5) * 0.5,
            );
            (300.0 + crater_h(x, y) + 8.0 * rough[i] as f64) as f32
        })
        .collect();
    let g0: Vec<f32> = (0..no * no).map(|_| rng.random_range(-1.0..1.0)).collect();
    let (fine, mid, coarse) = (blur(&g0, no, 1), blur(&g0, no, 4), blur(&g0, no, 16));
    let ortho: Vec<u8> = (0..no * no)
        .map(|i| {
            let (c, r) = (i % no, i / no);
            let (x, y) = (
                WEST + (c as f64 + 0.5) * 0.25,
                NORTH - (r as f64 + 0.5) * 0.25,
            );
            let floor = craters
                .iter()
                .any(|&(cx, cy, rr)| (x - cx).hypot(y - cy) < 0.8 * rr);
            let g = 110.0 + 60.0 * fine[i] + 120.0 * mid[i] + 200.0 * coarse[i]
                - if floor { 35.0 } else { 0.0 };
            g.clamp(5.0, 250.0) as u8
        })
        .collect();
    let (d, o) = (dir.join("dem.tif"), dir.join("ortho.tif"));
    write_dem_f32(
        &d,
        nd,
        nd,
        &dem,
        &Georeference::new(WEST, NORTH, 0.5).unwrap(),
    )
    .unwrap();
    write_ortho_u8(
        &o,
        no,
        no,
        &ortho,
        &Georeference::new(WEST, NORTH, 0.25).unwrap(),
    )
    .unwrap();
    (d, o)
}

#[test]
fn dem_site_map_is_the_orthoimage_and_the_fix_finds_two_stops() {
    let dir = tempfile::tempdir().unwrap();
    let (dem_path, ortho_path) = write_site(dir.path());
    let mut world = World::from_geotiff(&dem_path, &ortho_path).unwrap();
    let dem = world.dem().unwrap();
    assert_eq!(dem.map_source(), MapSource::Ortho);
    assert_eq!(dem.extent_m(), [WEST, NORTH - SIDE_M, WEST + SIDE_M, NORTH]);

    // The map on a grid aligned with the orthoimage's pixels is the orthoimage, pixel for pixel.
    let ortho = orbfix_host::geotiff::read_geotiff(&ortho_path).unwrap();
    let (cx, cy) = (WEST + 80.0, NORTH - 80.0);
    let m = map_region(
        &world,
        cx,
        cy,
        400,
        0.25,
        Sun::default(),
        &RenderOptions::default(),
    )
    .unwrap();
    let (c0, r0) = (120usize, 120usize); // (cx - 50 m - WEST) / 0.25
    for (k, &g) in m.image.iter().enumerate() {
        let (c, r) = (k % 400, k / 400);
        assert_eq!(
            g as f32,
            ortho.values[(r0 + r) * ortho.width + c0 + c],
            "map pixel ({c}, {r})"
        );
    }
    // At half the resolution it is the 2 x 2 mean (the renderer's footprint filtering).
    let half = map_region(
        &world,
        cx,
        cy,
        200,
        0.5,
        Sun::default(),
        &RenderOptions::default(),
    )
    .unwrap();
    let mean = |c: usize, r: usize| {
        let at = |dc, dr| ortho.values[(r0 + 2 * r + dr) * ortho.width + c0 + 2 * c + dc];
        (at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1)) / 4.0
    };
    assert!((half.image[17 * 200 + 33] as f32 - mean(33, 17)).abs() <= 0.5 + 1e-3);
    // The other source renders the DEM under the sun: not the orthoimage.
    let mut rendered = world.clone();
    rendered.set_dem_map_source(MapSource::Render);
    let mr = map_region(
        &rendered,
        cx,
        cy,
        400,
        0.25,
        Sun::default(),
        &RenderOptions::default(),
    )
    .unwrap();
    assert_ne!(mr.image, m.image);
    world.set_dem_map_source(MapSource::Ortho);

    // Two stops, priors 12-15 m off, 100 m maps from the orthoimage, the one fix.
    let opts = PipelineOptions {
        reprojection: Reprojection::Range,
        map_px: 400,
        ..PipelineOptions::default()
    };
    let stops = [
        ((1070.0, 2085.0), (1082.0, 2073.0), 40.0),
        ((1092.0, 2072.0), (1080.0, 2085.0), 250.0),
    ];
    for (truth, prior, heading) in stops {
        let Stop { obs, product, .. } = stop_on(&world, truth, prior, heading, &opts);
        let mut pose = obs.pose;
        pose.x_m = prior.0 as f32;
        pose.y_m = prior.1 as f32;
        let out = FixRunner::shipped(FixConfig::default())
            .run(
                &obs.params,
                &pose,
                obs.frames().unwrap(),
                obs.depths.as_ref(),
                &product,
            )
            .unwrap();
        let r = &out.report;
        let e = (r.x_m as f64 - truth.0).hypot(r.y_m as f64 - truth.1);
        // The position is the test; on this small site's blurred-noise texture the CNN's
        // coarse scores are close together, so the fix may call itself ambiguous (seen:
        // confidence 0.03 for a fix 1.4 cm off), but never no-data or on the border.
        assert!(
            matches!(r.status, FixStatus::Ok | FixStatus::Ambiguous),
            "stop {truth:?}: {r:?}"
        );
        assert_eq!(r.path, FixPath::Ncc, "stop {truth:?}: {r:?}");
        assert!(e < 1.0, "stop {truth:?}: fix error {e} m ({r:?})");
    }
}

/// `orbfix generate --dem --ortho`: a smoke dataset from the site, through the same world
/// (`World::from_geotiff`) and map code (`map_region`) as `orbfix map --dem` and `orbfix eval
/// --dem`; it opens with the dataset reader, its rows lie on the site with the DEM's heights,
/// its satellite crops are the orthoimage, it resumes, and bad files and options are refused.
#[test]
fn generate_renders_a_dataset_from_the_dem_site() {
    use orbfix_host::dataset::{self, Dataset, DemSite, GenerateConfig, Preset};
    let dir = tempfile::tempdir().unwrap();
    let (dem_path, ortho_path) = write_site(dir.path());
    let mut cfg = GenerateConfig::preset(Preset::Smoke, 4);
    cfg.range = true;
    // Smoke crops: 100 px at 0.5 m = 50 m, so the margin must be at least 25 m.
    cfg.dem = Some(DemSite::new(&dem_path, &ortho_path, MapSource::Ortho, 30.0).unwrap());
    let out = dir.path().join("ds");
    let rep = dataset::generate(&cfg, &out, None, false).unwrap();
    assert_eq!((rep.rendered, rep.skipped), (6, 0));

    let ds = Dataset::open(&out).unwrap();
    assert_eq!(ds.rows.len(), 6);
    let frame = ds
        .info
        .dem_frame
        .as_ref()
        .expect("dataset.json records the site's frame");
    assert_eq!(frame.crs_offset_m, [0.0, 0.0]);
    assert_eq!(frame.extent_m, [WEST, NORTH - SIDE_M, WEST + SIDE_M, NORTH]);
    let zone = [
        WEST + 30.0,
        NORTH - SIDE_M + 30.0,
        WEST + SIDE_M - 30.0,
        NORTH - 30.0,
    ];
    assert_eq!(ds.info.zones, vec![("dem".to_string(), zone)]);
    assert_eq!(ds.info.config.dem, cfg.dem);

    let world = World::from_geotiff(&dem_path, &ortho_path).unwrap();
    let ortho = orbfix_host::geotiff::read_geotiff(&ortho_path).unwrap();
    for row in &ds.rows {
        assert!(
            row.x_m >= zone[0] && row.x_m < zone[2] && row.y_m >= zone[1] && row.y_m < zone[3],
            "row {} at ({}, {}) is outside {zone:?}",
            row.id,
            row.x_m,
            row.y_m
        );
        // The DEM's heights (about 300 m on this site; the procedural world lies near 0).
        assert!((row.ground_z_m - world.height_m(row.x_m, row.y_m)).abs() < 1e-3);
        assert!(
            row.ground_z_m > 250.0 && row.ground_z_m < 350.0,
            "{}",
            row.ground_z_m
        );
        // Views: the site's ground, neither black nor saturated, in the lower half.
        for v in ds.load_views(row).unwrap() {
            let lower: Vec<f64> = v.rows().skip(60).flatten().map(|p| p[0] as f64).collect();
            let mean = lower.iter().sum::<f64>() / lower.len() as f64;
            assert!(
                mean > 10.0 && mean < 245.0,
                "row {} view mean {mean}",
                row.id
            );
        }
        // Satellite crop: the orthoimage's 2 x 2 means (0.5 m crop pixels over 0.25 m
        // orthoimage pixels, not aligned: compared with the nearest 2 x 2 block).
        let sat = ds.load_satellite(row).unwrap();
        let (x0, y0) = (row.x_m - 25.0, row.y_m + 25.0);
        let (mut sa, mut sb, mut saa, mut sbb, mut sab, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let mut abs = 0.0;
        for (c, r, p) in sat.enumerate_pixels() {
            let x = x0 + (c as f64 + 0.5) * 0.5;
            let y = y0 - (r as f64 + 0.5) * 0.5;
            let oc = ((x - WEST) / 0.25 - 1.0).round() as usize;
            let or = ((NORTH - y) / 0.25 - 1.0).round() as usize;
            let at = |dc: usize, dr: usize| ortho.values[(or + dr) * ortho.width + oc + dc] as f64;
            let want = (at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1)) / 4.0;
            let got = p[0] as f64;
            sa += got;
            sb += want;
            saa += got * got;
            sbb += want * want;
            sab += got * want;
            abs += (got - want).abs();
            n += 1.0;
        }
        let corr = (sab / n - sa / n * sb / n)
            / ((saa / n - (sa / n).powi(2)).sqrt() * (sbb / n - (sb / n).powi(2)).sqrt());
        assert!(
            corr > 0.9,
            "row {}: crop vs orthoimage correlation {corr}",
            row.id
        );
        assert!(
            abs / n < 12.0,
            "row {}: mean |crop - orthoimage| {}",
            row.id,
            abs / n
        );
        let range = row.range.as_ref().expect("range images were asked for");
        assert!(range.iter().all(|p| out.join(p).is_file()));
    }
    // Rows are a pure function of (config, index) on a DEM site too.
    let w = cfg.world().unwrap();
    assert_eq!(cfg.location(&w, 5).unwrap(), ds.rows[5]);

    // Resume: everything is kept.
    let again = dataset::generate(&cfg, &out, None, false).unwrap();
    assert_eq!((again.rendered, again.skipped), (0, 6));

    // Bad files and options, each with a message that says what is wrong.
    let err = |r: anyhow::Result<()>| format!("{:#}", r.unwrap_err());
    let missing = dir.path().join("missing.tif");
    let e = err(DemSite::new(&missing, &ortho_path, MapSource::Ortho, 30.0).map(|_| ()));
    assert!(
        e.contains("cannot open the DEM") && e.contains("missing.tif"),
        "{e}"
    );
    let e = err(DemSite::new(&dem_path, dir.path(), MapSource::Ortho, 30.0).map(|_| ()));
    assert!(
        e.contains("orthoimage") && e.contains("not a regular file"),
        "{e}"
    );
    let not_tiff = out.join("manifest.jsonl");
    let mut bad = cfg.clone();
    bad.dem = Some(DemSite::new(&not_tiff, &ortho_path, MapSource::Ortho, 30.0).unwrap());
    let e = err(dataset::generate(&bad, &dir.path().join("bad"), None, false).map(|_| ()));
    assert!(e.contains("reading the DEM"), "{e}");
    assert!(
        !dir.path().join("bad").exists(),
        "nothing is written for a bad DEM"
    );
    let mut wide = cfg.clone();
    wide.dem.as_mut().unwrap().margin_m = 90.0;
    let e = err(dataset::generate(&wide, &dir.path().join("wide"), None, false).map(|_| ()));
    assert!(
        e.contains("--dem-margin 90") && e.contains("x 1000.0..1160.0"),
        "{e}"
    );
    let mut thin = cfg.clone();
    thin.dem.as_mut().unwrap().margin_m = 10.0;
    let e = err(thin.validate());
    assert!(e.contains("half the satellite crop"), "{e}");
    let mut flat = cfg.clone();
    flat.flat = true;
    assert!(err(flat.validate()).contains("--flat"));

    // A changed orthoimage: the old configuration refuses it, a new one is another dataset.
    let inverted: Vec<u8> = ortho.values.iter().map(|&v| 255 - v as u8).collect();
    write_ortho_u8(
        &ortho_path,
        ortho.width,
        ortho.height,
        &inverted,
        &Georeference::new(WEST, NORTH, 0.25).unwrap(),
    )
    .unwrap();
    let e = err(cfg.world().map(|_| ()));
    assert!(e.contains("changed since"), "{e}");
    let mut changed = cfg.clone();
    changed.dem = Some(DemSite::new(&dem_path, &ortho_path, MapSource::Ortho, 30.0).unwrap());
    let e = err(dataset::generate(&changed, &out, None, false).map(|_| ()));
    assert!(e.contains("other options"), "{e}");
}
