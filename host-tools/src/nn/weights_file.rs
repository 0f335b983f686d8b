//! Loading a `.ofw` weight file on the host: read, validate with the core's parser, and
//! return an owned network (`--weights FILE` of the subcommands that run the CNN).

use anyhow::Context;
use orbfix::nn::matcher::CnnMatcher;
use orbfix::nn::model::{SiameseNet, SHIPPED_WEIGHTS};
use std::path::{Path, PathBuf};

/// The `--weights FILE` option, to `#[command(flatten)]` into a subcommand's arguments.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct WeightsArg {
    /// Weight file of the CNN matcher (.ofw, written by `orbfix quantize`); default: the
    /// weights shipped in the core (weights/matcher-v2.ofw). Checked (CRC, shapes,
    /// quantization ranges, accumulator bound) before use.
    #[arg(long, value_name = "FILE")]
    pub weights: Option<PathBuf>,
}

impl WeightsArg {
    /// The validated network of `--weights` (or the shipped one).
    pub fn load(&self) -> anyhow::Result<SiameseNet<'static>> {
        load_net(self.weights.as_deref())
    }

    /// The CNN matcher running the network of `--weights` (or the shipped one).
    pub fn matcher(&self) -> anyhow::Result<CnnMatcher<'static>> {
        Ok(CnnMatcher::new(self.load()?))
    }

    /// The validated bytes of `--weights` (or of the shipped weights), for the core's fix,
    /// the map product and the firmware's vectors.
    pub fn bytes(&self) -> anyhow::Result<Vec<u8>> {
        load_bytes(self.weights.as_deref())
    }

    /// What to print as the weights' name: the file, or "shipped".
    pub fn describe(&self) -> String {
        match &self.weights {
            Some(p) => p.display().to_string(),
            None => "shipped (weights/matcher-v2.ofw)".into(),
        }
    }
}

/// The bytes of the weight file at `path` (`None`: the shipped weights), validated by the
/// core's parser (CRC first, then structure and quantization bounds). The error names the
/// file and what is wrong with it.
pub fn load_bytes(path: Option<&Path>) -> anyhow::Result<Vec<u8>> {
    let Some(path) = path else {
        SiameseNet::from_bytes(SHIPPED_WEIGHTS)
            .context("the shipped weights do not validate (a damaged build?)")?;
        return Ok(SHIPPED_WEIGHTS.to_vec());
    };
    let bytes = std::fs::read(path).with_context(|| {
        format!(
            "cannot read the weight file {} (missing or unreadable?)",
            path.display()
        )
    })?;
    if let Err(e) = SiameseNet::from_bytes(&bytes) {
        anyhow::bail!("{}: {e}", path.display());
    }
    Ok(bytes)
}

/// Reads and validates the weight file at `path` (`None`: the shipped weights). The bytes
/// are kept for the life of the program (a CLI loads one or two files), so the network is
/// `'static` and can go behind `Box<dyn Matcher + Send + Sync>`.
pub fn load_net(path: Option<&Path>) -> anyhow::Result<SiameseNet<'static>> {
    let Some(path) = path else {
        return SiameseNet::from_bytes(SHIPPED_WEIGHTS)
            .context("the shipped weights do not validate (a damaged build?)");
    };
    let bytes: &'static [u8] = Box::leak(load_bytes(Some(path))?.into_boxed_slice());
    SiameseNet::from_bytes(bytes).with_context(|| format!("weight file {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loads_the_shipped_and_a_copy_and_refuses_a_damaged_file() {
        assert!(load_net(None).is_ok());
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("good.ofw");
        std::fs::write(&good, SHIPPED_WEIGHTS).unwrap();
        let a = WeightsArg {
            weights: Some(good),
        };
        assert!(a.matcher().is_ok());
        let mut bad = SHIPPED_WEIGHTS.to_vec();
        bad[100] ^= 4;
        let badp = dir.path().join("bad.ofw");
        std::fs::write(&badp, &bad).unwrap();
        let e = load_net(Some(&badp)).unwrap_err();
        let msg = format!("{e:#}");
        assert!(msg.contains("bad.ofw") && msg.contains("corrupt"), "{msg}");
        let e = load_net(Some(&dir.path().join("missing.ofw"))).unwrap_err();
        assert!(format!("{e:#}").contains("cannot read"), "{e:#}");
    }
}
