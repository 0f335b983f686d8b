//! `orbfix prepare-inputs`: real network inputs of a generated dataset as one `.npy` batch,
//! for `orbfix embed` and other runtimes (`scripts/tflm-check.sh`).

use anyhow::{ensure, Context, Result};
use orbfix::nn::input::{prepare_input, INPUT_LEN, INPUT_SIDE};
use orbfix::reproject::GridSpec;
use orbfix_host::dataset::Dataset;
use orbfix_host::npy::write_i8;
use rayon::prelude::*;
use std::path::PathBuf;

/// Write the core's network inputs (`prepare_input`) of every location of a dataset written
/// by `orbfix generate`: per location the rover top-down image (its four views reprojected
/// with the flight core's lookup table onto the satellite crop's grid, no-data cells masked)
/// and the satellite crop, as one int8 NumPy array [N, 64, 64, 1] (rover then satellite,
/// locations in manifest order). Inputs the core refuses (too few valid cells, no contrast)
/// are left out and counted.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Dataset folder (written by `orbfix generate`).
    #[arg(long)]
    pub dataset: PathBuf,
    /// Batch to write (.npy, int8, [N, 64, 64, 1]).
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(a: Args) -> Result<()> {
    let ds = Dataset::open(&a.dataset)
        .with_context(|| format!("opening dataset {}", a.dataset.display()))?;
    let side = ds.info.config.satellite_px as usize;
    let res = ds.info.config.satellite_m_per_px as f32;
    ensure!(
        side >= INPUT_SIDE,
        "the dataset's satellite crops are {side} px; the network needs at least {INPUT_SIDE}"
    );
    let grid = GridSpec::new(side, res);
    let per_loc: Vec<[Option<[i8; INPUT_LEN]>; 2]> = ds
        .rows
        .par_iter()
        .map(|row| -> Result<_> {
            let td = super::reproject::top_down(&ds, row, &grid, &[])?;
            let sat = ds
                .load_satellite(row)
                .with_context(|| format!("loading the satellite crop of {}", row.id))?;
            let mut rover = [0i8; INPUT_LEN];
            let mut crop = [0i8; INPUT_LEN];
            let rover = prepare_input(&td.image, Some(&td.mask), td.n, &mut rover)
                .ok()
                .map(|_| rover);
            let crop = prepare_input(sat.as_raw(), None, side, &mut crop)
                .ok()
                .map(|_| crop);
            Ok([rover, crop])
        })
        .collect::<Result<_>>()?;
    let inputs: Vec<&[i8; INPUT_LEN]> = per_loc.iter().flatten().flatten().collect();
    let refused = 2 * per_loc.len() - inputs.len();
    ensure!(
        !inputs.is_empty(),
        "the core refused every input of {} (flat or empty images)",
        a.dataset.display()
    );
    let data: Vec<i8> = inputs.iter().flat_map(|x| x.iter().copied()).collect();
    let bytes = write_i8(&[inputs.len(), INPUT_SIDE, INPUT_SIDE, 1], &data)?;
    orbfix_host::fsutil::write_atomic(&a.out, &bytes)?;
    println!(
        "wrote {} ({} inputs from {} locations; {refused} refused by prepare_input)",
        a.out.display(),
        inputs.len(),
        per_loc.len()
    );
    Ok(())
}
