//! `orbfix localize`: one fix from a dataset location (or a top-down image) and a map, with
//! a JSON result and two pictures for operators.

use anyhow::{bail, Context};
use orbfix::localize::{nearest_window, rank_of, LocalizeConfig};
use orbfix_host::eval::{
    describe_fix, load_map, localize_top_down, matcher_by_name, overlay, pipeline, save_png_atomic,
    write_atomic, TopDown, MATCHERS,
};
use std::path::PathBuf;

/// Localize one rover stop in an orbital map.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Examples:\n  orbfix localize --dataset data/ds --id 000012 --map out/map.png --map-meta out/map.json --out out/loc\n  orbfix localize --top top.png --mask mask.png --map out/map.png --map-meta out/map.json --prior-x 3000 --prior-y 2000 --out out/loc"
)]
pub struct Args {
    /// Dataset folder (`orbfix generate`); with --id.
    #[arg(long, requires = "id")]
    pub dataset: Option<PathBuf>,
    /// Location id in the dataset's manifest.
    #[arg(long)]
    pub id: Option<String>,
    /// A top-down image (north-up, centred on the rover, 0.25 m/px) instead of a dataset.
    #[arg(long, conflicts_with = "dataset")]
    pub top: Option<PathBuf>,
    /// Validity mask of --top (0 = no data); default: all valid.
    #[arg(long, requires = "top")]
    pub mask: Option<PathBuf>,
    /// Metres per pixel of --top.
    #[arg(long, allow_negative_numbers = true, value_parser = crate::cmd::num::positive_f32, default_value_t = 0.25)]
    pub top_m_per_px: f32,
    /// Map image (8-bit gray PNG, north-up).
    #[arg(long)]
    pub map: PathBuf,
    /// Map georeference (JSON written by `orbfix map`).
    #[arg(long)]
    pub map_meta: PathBuf,
    /// Prior east, metres (default: the map's centre).
    #[arg(long, allow_negative_numbers = true)]
    pub prior_x: Option<f64>,
    /// Prior north, metres (default: the map's centre).
    #[arg(long, allow_negative_numbers = true)]
    pub prior_y: Option<f64>,
    /// Matcher (ncc, ncc-dist, l1, l2).
    #[arg(long, default_value = "ncc")]
    pub matcher: String,
    /// Output folder: result.json, topdown.png, map.png.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let spec = matcher_by_name(&a.matcher)
        .with_context(|| format!("--matcher (available: {})", MATCHERS.join(", ")))?;
    let map = load_map(&a.map, &a.map_meta)?;
    let (top, truth) = match (&a.dataset, &a.top) {
        (Some(ds), _) => {
            let id = a.id.as_deref().context("--dataset needs --id")?;
            pipeline::dataset_top_down(ds, id)?
        }
        (None, Some(t)) => (load_top(t, a.mask.as_ref(), a.top_m_per_px)?, None),
        (None, None) => bail!("give a rover stop: --dataset DIR --id ID, or --top TOP.png"),
    };
    let centre = map
        .geo
        .to_world(map.width as f32 / 2.0, map.height as f32 / 2.0);
    let prior = (
        a.prior_x.unwrap_or(centre.0 as f64),
        a.prior_y.unwrap_or(centre.1 as f64),
    );
    let loc = localize_top_down(&spec, &top, &map, prior, &LocalizeConfig::default(), 50)?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create the output folder {}", a.out.display()))?;
    let mut json = describe_fix(&loc);
    json["matcher"] = a.matcher.clone().into();
    json["prior_m"] = serde_json::json!([prior.0, prior.1]);
    if let Some((tx, ty)) = truth {
        let err = ((loc.fix.x_m as f64 - tx).powi(2) + (loc.fix.y_m as f64 - ty).powi(2)).sqrt();
        let tw = nearest_window(
            &loc.window_grid,
            &map.geo,
            top.n,
            top.n,
            tx as f32,
            ty as f32,
        );
        json["truth_m"] = serde_json::json!([tx, ty]);
        json["error_m"] = err.into();
        json["true_window_rank"] =
            (rank_of(&loc.window_scores, tw).unwrap_or(usize::MAX) + 1).into();
    }
    write_atomic(
        &a.out.join("result.json"),
        serde_json::to_string_pretty(&json)?.as_bytes(),
    )?;
    save_png_atomic(&overlay::top_down_picture(&top), &a.out.join("topdown.png"))?;
    save_png_atomic(
        &overlay::map_picture(&map, &loc, top.n, truth, prior, 1),
        &a.out.join("map.png"),
    )?;
    println!(
        "fix ({:.2}, {:.2}) m, confidence {:.2}{}; {}",
        loc.fix.x_m,
        loc.fix.y_m,
        loc.fix.confidence,
        if loc.fix.on_border {
            ", ON THE SEARCH BORDER (rejected)"
        } else {
            ""
        },
        a.out.display()
    );
    Ok(())
}

fn load_top(path: &PathBuf, mask: Option<&PathBuf>, m_per_px: f32) -> anyhow::Result<TopDown> {
    let img = image::open(path)
        .with_context(|| format!("cannot read the top-down image {}", path.display()))?
        .to_luma8();
    if img.width() != img.height() {
        bail!(
            "{} is {} x {} px: the top-down image must be square",
            path.display(),
            img.width(),
            img.height()
        );
    }
    let n = img.width() as usize;
    let mask = match mask {
        Some(p) => {
            let m = image::open(p)
                .with_context(|| format!("cannot read the mask {}", p.display()))?
                .to_luma8();
            if m.dimensions() != img.dimensions() {
                bail!(
                    "mask {} is {:?} px, the image {:?}",
                    p.display(),
                    m.dimensions(),
                    img.dimensions()
                );
            }
            m.into_raw()
        }
        None => vec![255; n * n],
    };
    if !(m_per_px.is_finite() && m_per_px > 0.0) {
        bail!("--top-m-per-px must be a positive number of metres");
    }
    Ok(TopDown {
        image: img.into_raw(),
        mask,
        n,
        m_per_px,
    })
}
