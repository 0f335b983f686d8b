//! Atomic file writes and deterministic PNG encoding.

use anyhow::{bail, Context};
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, GrayImage, ImageEncoder};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Refuses an output `path` that exists and is not a regular file (what [`write_atomic`]
/// refuses), so that a command can say so before its long work; `-` (standard output) and
/// paths that do not exist yet pass.
pub fn check_output(path: &Path) -> anyhow::Result<()> {
    if path.as_os_str() == "-" {
        return Ok(());
    }
    match std::fs::metadata(path) {
        Ok(m) if !m.is_file() => bail!(
            "{} is not a regular file ({}); give the path of a file to write, or - for standard output",
            path.display(),
            if m.is_dir() { "a folder" } else { "a device, pipe or socket" }
        ),
        _ => Ok(()),
    }
}

/// Writes `bytes` to `path` atomically: a temporary file in the same folder, fsync, rename.
/// A reader never sees a partial file; an interrupted write leaves at most a `.tmp` file.
///
/// Only regular files are written: a `path` that exists and is not a regular file (a device
/// such as `/dev/full`, a folder, a pipe; symbolic links are followed) is refused, never
/// renamed over. `-` writes to standard output instead (a closed pipe ends the program
/// quietly, see `main`).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    if path.as_os_str() == "-" {
        let mut out = std::io::stdout().lock();
        out.write_all(bytes)
            .and_then(|()| out.flush())
            .context("cannot write to standard output")?;
        return Ok(());
    }
    check_output(path)?;
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .with_context(|| format!("{} has no file name", path.display()))?;
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".{}.tmp", std::process::id()));
    let tmp: PathBuf = dir.join(tmp_name);
    let res = (|| -> anyhow::Result<()> {
        let mut f = std::fs::File::create(&tmp).with_context(|| {
            format!("cannot create {} (is the folder writable?)", tmp.display())
        })?;
        f.write_all(bytes)
            .with_context(|| format!("cannot write {} (disk full?)", tmp.display()))?;
        f.sync_all()
            .with_context(|| format!("cannot sync {}", tmp.display()))?;
        std::fs::rename(&tmp, path)
            .with_context(|| format!("cannot rename {} to {}", tmp.display(), path.display()))?;
        Ok(())
    })();
    if res.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    res
}

/// PNG bytes of an 8-bit gray image, with fixed encoder settings (deterministic).
pub fn png_gray8(img: &GrayImage) -> anyhow::Result<Vec<u8>> {
    let mut out = Vec::new();
    PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Sub)
        .write_image(
            img.as_raw(),
            img.width(),
            img.height(),
            ExtendedColorType::L8,
        )
        .context("encoding PNG")?;
    Ok(out)
}

/// PNG bytes of a 16-bit gray raster (row-major values), fixed settings. The file holds the
/// values big-endian, as the PNG standard requires (the encoder takes native-endian samples
/// and swaps them itself), so every PNG reader (Pillow, libpng, GDAL) reads the same values.
pub fn png_gray16(w: u32, h: u32, values: &[u16]) -> anyhow::Result<Vec<u8>> {
    if values.len() != w as usize * h as usize {
        bail!(
            "16-bit raster has {} values, expected {}x{}",
            values.len(),
            w,
            h
        );
    }
    // The encoder takes native-endian samples (it writes PNG's big-endian itself).
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_ne_bytes()).collect();
    let mut out = Vec::new();
    PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Sub)
        .write_image(&bytes, w, h, ExtendedColorType::L16)
        .context("encoding 16-bit PNG")?;
    Ok(out)
}

/// Writes an 8-bit gray PNG atomically.
pub fn write_png(path: &Path, img: &GrayImage) -> anyhow::Result<()> {
    write_atomic(path, &png_gray8(img)?)
}

/// Reads an 8-bit gray PNG and checks its size (`None`: any size). Errors name the file and
/// say whether it is missing, corrupt/truncated, of the wrong kind or the wrong size.
pub fn read_gray_png(path: &Path, size: Option<(u32, u32)>) -> anyhow::Result<GrayImage> {
    let bytes = std::fs::read(path)
        .with_context(|| format!("cannot read {} (missing?)", path.display()))?;
    let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png).with_context(
        || {
            format!(
                "{} is not a valid PNG (corrupt or truncated?)",
                path.display()
            )
        },
    )?;
    if img.color() != image::ColorType::L8 {
        bail!(
            "{} is {}, expected 8-bit gray: convert it (e.g. `convert IN -colorspace Gray -depth 8 OUT.png`)",
            path.display(),
            describe_color(img.color())
        );
    }
    let img = img.to_luma8();
    if let Some((w, h)) = size {
        if img.dimensions() != (w, h) {
            bail!(
                "{} is {}x{}, expected {}x{}",
                path.display(),
                img.width(),
                img.height(),
                w,
                h
            );
        }
    }
    Ok(img)
}

/// The colour type of an image in words, for messages.
fn describe_color(c: image::ColorType) -> String {
    use image::ColorType as C;
    let kind = match c {
        C::L8 | C::L16 => "gray",
        C::La8 | C::La16 => "gray with alpha",
        C::Rgb8 | C::Rgb16 | C::Rgb32F => "colour (RGB)",
        C::Rgba8 | C::Rgba16 | C::Rgba32F => "colour with alpha (RGBA)",
        _ => "of an unusual colour type",
    };
    let bits = c.bits_per_pixel() / u16::from(c.channel_count().max(1));
    format!("{bits}-bit {kind}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gray16_png_round_trips_through_the_decoder() {
        let v = [1u16, 302, 0x2E01, 65535, 0, 4096];
        let png = png_gray16(3, 2, &v).unwrap();
        let img = image::load_from_memory_with_format(&png, image::ImageFormat::Png)
            .unwrap()
            .into_luma16();
        assert_eq!(img.as_raw().as_slice(), &v);
    }

    #[test]
    fn writes_regular_files_and_refuses_devices_and_folders() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("a.bin");
        write_atomic(&f, b"one").unwrap();
        write_atomic(&f, b"two").unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"two");
        let e = write_atomic(dir.path(), b"x").unwrap_err().to_string();
        assert!(
            e.contains("not a regular file") && e.contains("folder"),
            "{e}"
        );
        assert!(dir.path().is_dir(), "the folder is untouched");
        if Path::new("/dev/null").exists() {
            let e = write_atomic(Path::new("/dev/null"), b"x")
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("not a regular file") && e.contains("device"),
                "{e}"
            );
            let m = std::fs::metadata("/dev/null").unwrap();
            assert!(!m.is_file(), "/dev/null is still the device");
        }
        // No temporary file is left behind by a refusal.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_colour_png_is_named_in_words() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("rgb.png");
        image::RgbImage::from_pixel(4, 4, image::Rgb([16, 32, 48]))
            .save(&p)
            .unwrap();
        let e = format!("{:#}", read_gray_png(&p, None).unwrap_err());
        assert!(e.contains("8-bit colour (RGB), expected 8-bit gray"), "{e}");
        assert!(!e.contains("Rgb8"), "{e}");
        let g = dir.path().join("g.png");
        write_png(&g, &GrayImage::from_pixel(4, 4, image::Luma([7]))).unwrap();
        assert_eq!(
            read_gray_png(&g, Some((4, 4))).unwrap().get_pixel(0, 0).0,
            [7]
        );
    }
}
