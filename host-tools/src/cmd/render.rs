//! `orbfix render`: pictures for people (one location, a map region, or the docs figure).

use anyhow::Context;
use image::GrayImage;
use orbfix::geo::GeoRef;
use orbfix_host::fsutil::write_png;
use orbfix_host::render::{self, RenderOptions, Sun};
use orbfix_host::world::World;
use std::path::{Path, PathBuf};

/// Render one location (four views + satellite crop), a map region, or the overview figure
/// of docs/ to PNG.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(clap::Args, Debug, Clone)]
struct Common {
    /// World seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Zero relief, same albedo.
    #[arg(long)]
    flat: bool,
    /// Sun elevation, degrees above the horizon (0..=90).
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    sun_elevation: f64,
    /// Sun azimuth, degrees clockwise from north, towards the sun (0..360).
    #[arg(long, default_value_t = 135.0, allow_negative_numbers = true)]
    sun_azimuth: f64,
    /// Photometric function.
    #[arg(long, value_enum, default_value = "lunar-lambert")]
    photometry: Phot,
    /// Gaussian sensor noise, gray levels.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::non_negative_f64, default_value_t = 0.0)]
    noise: f64,
    /// Half side of the square around the rover where the views show the world's
    /// micro-relief (roughness, pits, clods, pebbles; docs/rendering.md), metres; 0 = none,
    /// the mesh's smooth shading only.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::non_negative_f64, default_value_t = 10.0)]
    detail_range: f64,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum Phot {
    Lambert,
    LommelSeeliger,
    LunarLambert,
}

#[derive(clap::Subcommand, Debug)]
enum What {
    /// The four ground views and the satellite crop of one location: writes
    /// front.png, right.png, rear.png, left.png, satellite.png and views.png (all in a row).
    Location {
        #[command(flatten)]
        common: Common,
        /// Rover east, metres.
        #[arg(long, allow_negative_numbers = true, default_value_t = 1000.0)]
        x: f64,
        /// Rover north, metres.
        #[arg(long, allow_negative_numbers = true, default_value_t = 1000.0)]
        y: f64,
        /// Heading, degrees clockwise from north.
        #[arg(long, allow_negative_numbers = true, default_value_t = 0.0)]
        heading: f64,
        /// Pitch, degrees, nose up positive.
        #[arg(long, allow_negative_numbers = true, default_value_t = 0.0)]
        pitch: f64,
        /// Roll, degrees, right side down positive.
        #[arg(long, allow_negative_numbers = true, default_value_t = 0.0)]
        roll: f64,
        /// View size WxH, pixels.
        #[arg(long, default_value = "640x360")]
        size: String,
        /// Horizontal field of view, degrees (< 180).
        #[arg(long, allow_negative_numbers = true, default_value_t = 90.0)]
        hfov: f32,
        /// Satellite crop side, pixels.
        #[arg(long, default_value_t = 200)]
        sat_px: u32,
        /// Satellite crop resolution, metres per pixel.
        #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::positive_f64, default_value_t = 0.25)]
        sat_m_per_px: f64,
        /// Also write a PLY point cloud (cloud.ply) from the range images.
        #[arg(long)]
        point_cloud: bool,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
    },
    /// A north-up map region centred on (x, y): writes one PNG and prints its georeference.
    Map {
        #[command(flatten)]
        common: Common,
        /// Centre east, metres.
        #[arg(long, allow_negative_numbers = true, default_value_t = 1000.0)]
        x: f64,
        /// Centre north, metres.
        #[arg(long, allow_negative_numbers = true, default_value_t = 1000.0)]
        y: f64,
        /// Side of the region, metres.
        #[arg(long, default_value_t = 300.0, allow_negative_numbers = true)]
        size_m: f64,
        /// Resolution, metres per pixel.
        #[arg(long, default_value_t = 0.25, allow_negative_numbers = true)]
        m_per_px: f64,
        /// Output PNG.
        #[arg(long)]
        out: PathBuf,
    },
    /// The near-field figure of docs/: the lower middle of one 1920 x 1080 view (960 x 540
    /// px, the ground from 2 to about 8 m) drawn twice, left with the mesh's shading only
    /// (`--detail-range 0`, as views were drawn before the micro-relief), right with the
    /// world's micro-relief (roughness, pits, clods, pebbles, sharp cast shadows).
    NearField {
        #[command(flatten)]
        common: Common,
        /// Rover east, metres.
        #[arg(long, allow_negative_numbers = true, default_value_t = 1000.0)]
        x: f64,
        /// Rover north, metres.
        #[arg(long, allow_negative_numbers = true, default_value_t = 1000.0)]
        y: f64,
        /// Heading of the view, degrees clockwise from north.
        #[arg(long, allow_negative_numbers = true, default_value_t = 270.0)]
        heading: f64,
        /// Output PNG.
        #[arg(long, default_value = "docs/figures/near-field.png")]
        out: PathBuf,
    },
    /// The overview figure of docs/: the four views (front, right / rear, left), the 50 m
    /// satellite crop (0.25 m/px, shown 2x) and the 300 m map region around it (0.5 m/px,
    /// the crop outlined).
    Figure {
        #[command(flatten)]
        common: Common,
        /// Rover east, metres.
        #[arg(long, allow_negative_numbers = true, default_value_t = 1000.0)]
        x: f64,
        /// Rover north, metres.
        #[arg(long, allow_negative_numbers = true, default_value_t = 1000.0)]
        y: f64,
        /// Output PNG.
        #[arg(long, default_value = "docs/figures/world-overview.png")]
        out: PathBuf,
    },
}

fn options(c: &Common) -> anyhow::Result<(World, Sun, RenderOptions)> {
    let world = if c.flat {
        World::flat(c.seed)
    } else {
        World::new(c.seed)
    };
    let sun = Sun::new(c.sun_elevation, c.sun_azimuth)?;
    let mut opts = RenderOptions {
        noise_sigma: c.noise,
        detail_range_m: c.detail_range,
        ..Default::default()
    };
    opts.photometry = match c.photometry {
        Phot::Lambert => render::Photometry::Lambert,
        Phot::LommelSeeliger => render::Photometry::LommelSeeliger,
        Phot::LunarLambert => render::Photometry::LunarLambert { weight: 0.5 },
    };
    opts.validate()?;
    Ok((world, sun, opts))
}

fn ensure_dir(p: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(p).with_context(|| {
        format!(
            "cannot create folder {} (check the path and permissions)",
            p.display()
        )
    })
}

/// Pastes images left to right (top-aligned) with `gap` pixels of mid gray between.
pub fn row_of(images: &[&GrayImage], gap: u32) -> GrayImage {
    let w: u32 =
        images.iter().map(|i| i.width()).sum::<u32>() + gap * images.len().saturating_sub(1) as u32;
    let h = images.iter().map(|i| i.height()).max().unwrap_or(1);
    let mut out = GrayImage::from_pixel(w.max(1), h.max(1), image::Luma([96]));
    let mut x0 = 0;
    for img in images {
        image::imageops::replace(&mut out, *img, x0 as i64, 0);
        x0 += img.width() + gap;
    }
    out
}

/// Stacks images top to bottom (left-aligned).
pub fn column_of(images: &[&GrayImage], gap: u32) -> GrayImage {
    let h: u32 = images.iter().map(|i| i.height()).sum::<u32>()
        + gap * images.len().saturating_sub(1) as u32;
    let w = images.iter().map(|i| i.width()).max().unwrap_or(1);
    let mut out = GrayImage::from_pixel(w.max(1), h.max(1), image::Luma([96]));
    let mut y0 = 0;
    for img in images {
        image::imageops::replace(&mut out, *img, 0, y0 as i64);
        y0 += img.height() + gap;
    }
    out
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.what {
        What::Location {
            common,
            x,
            y,
            heading,
            pitch,
            roll,
            size,
            hfov,
            sat_px,
            sat_m_per_px,
            point_cloud,
            out,
        } => {
            let (world, sun, mut opts) = options(&common)?;
            let (w, h) = super::generate::parse_size(&size)?;
            opts.camera.width_px = w;
            opts.camera.height_px = h;
            opts.camera.hfov_deg = hfov;
            opts.validate()?;
            let mut pose = render::ground_pose(&world, x, y, heading);
            pose.pitch_deg = pitch as f32;
            pose.roll_deg = roll as f32;
            ensure_dir(&out)?;
            let set = render::render_views_with_range(&world, &pose, sun, &opts)?;
            for (img, name) in set.views.iter().zip(orbfix_host::dataset::VIEW_NAMES) {
                write_png(&out.join(format!("{name}.png")), img)?;
            }
            let (sat, geo) =
                render::render_satellite_crop(&world, x, y, sat_px, sat_m_per_px, sun, &opts)?;
            write_png(&out.join("satellite.png"), &sat)?;
            let v = &set.views;
            write_png(
                &out.join("views.png"),
                &row_of(&[&v[0], &v[1], &v[2], &v[3]], 4),
            )?;
            if point_cloud {
                let mut pts = Vec::new();
                for k in 0..4 {
                    pts.extend(render::ply::points_from_range(
                        &set.cameras[k],
                        &set.range_m[k],
                        &set.views[k],
                        2,
                    ));
                }
                render::ply::write_ply(&out.join("cloud.ply"), &pts)?;
            }
            println!(
                "wrote {} (satellite NW corner ({:.3}, {:.3}) m, {} m/px)",
                out.display(),
                geo.origin_x_m(),
                geo.origin_y_m(),
                geo.m_per_px()
            );
        }
        What::Map {
            common,
            x,
            y,
            size_m,
            m_per_px,
            out,
        } => {
            let (world, sun, opts) = options(&common)?;
            anyhow::ensure!(
                size_m.is_finite() && size_m > 0.0,
                "--size-m {size_m} must be > 0"
            );
            anyhow::ensure!(
                m_per_px.is_finite() && m_per_px > 0.0,
                "--m-per-px {m_per_px} must be > 0"
            );
            let n = (size_m / m_per_px).round() as u32;
            let geo = GeoRef::centred(x as f32, y as f32, n as usize, n as usize, m_per_px as f32)
                .map_err(|e| anyhow::anyhow!("bad map georeference: {e}"))?;
            let img = render::render_ortho(&world, &geo, n, n, sun, &opts)?;
            if let Some(p) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
                ensure_dir(p)?;
            }
            write_png(&out, &img)?;
            println!(
                "wrote {} ({n}x{n} px, NW corner ({:.3}, {:.3}) m, {} m/px)",
                out.display(),
                geo.origin_x_m(),
                geo.origin_y_m(),
                geo.m_per_px()
            );
        }
        What::NearField {
            common,
            x,
            y,
            heading,
            out,
        } => {
            let (world, sun, mut opts) = options(&common)?;
            opts.camera.width_px = 1920;
            opts.camera.height_px = 1080;
            opts.validate()?;
            let pose = render::ground_pose(&world, x, y, heading);
            let smooth = RenderOptions {
                detail_range_m: 0.0,
                ..opts
            };
            let a = &render::render_views(&world, &pose, sun, &smooth)?[0];
            let b = &render::render_views(&world, &pose, sun, &opts)?[0];
            let crop =
                |img: &GrayImage| image::imageops::crop_imm(img, 480, 540, 960, 540).to_image();
            let fig = row_of(&[&crop(a), &crop(b)], 8);
            if let Some(p) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
                ensure_dir(p)?;
            }
            write_png(&out, &fig)?;
            println!("wrote {}", out.display());
        }
        What::Figure { common, x, y, out } => {
            let (world, sun, opts) = options(&common)?;
            let pose = render::ground_pose(&world, x, y, 0.0);
            let views = render::render_views(&world, &pose, sun, &opts)?;
            let (sat, _) = render::render_satellite_crop(&world, x, y, 200, 0.25, sun, &opts)?;
            // 300 m map at 0.5 m/px, the crop's 50 m square outlined in its centre.
            let geo = GeoRef::centred(x as f32, y as f32, 600, 600, 0.5)
                .map_err(|e| anyhow::anyhow!("bad map georeference: {e}"))?;
            let mut map = render::render_ortho(&world, &geo, 600, 600, sun, &opts)?;
            for k in 250..=350u32 {
                for (a, b) in [(k, 250), (k, 350), (250, k), (350, k)] {
                    map.put_pixel(a, b, image::Luma([255]));
                }
            }
            let sat = image::imageops::resize(&sat, 400, 400, image::imageops::FilterType::Nearest);
            let top = row_of(&[&views[0], &views[1]], 4);
            let mid = row_of(&[&views[2], &views[3]], 4);
            let bottom = row_of(&[&sat, &map], 4);
            let fig = column_of(&[&top, &mid, &bottom], 4);
            if let Some(p) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
                ensure_dir(p)?;
            }
            write_png(&out, &fig)?;
            println!("wrote {}", out.display());
        }
    }
    Ok(())
}
