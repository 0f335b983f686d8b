//! Property tests ("fuzzing" on the stable toolchain: cargo-fuzz needs nightly) of the core's
//! boundaries: the weight parser, `reproject`, the `ImageView` / `Grid` / `GeoRef`
//! constructors and `highpass`, on arbitrary sizes, strides, bytes and angles (NaN and
//! infinities included). Each property runs a fixed number of cases (seeded, so CI is
//! repeatable and bounded, well under a minute); the count of inputs tried is printed
//! (`cargo test --test fuzz_boundaries -- --nocapture`). A panic anywhere is a failure:
//! in the dev profile that includes every integer overflow.

use orbfix::camera::{CameraParams, RoverPose};
use orbfix::geo::{GeoRef, MAX_ORIGIN_M};
use orbfix::image::{ImageView, ImageViewMut};
use orbfix::matcher::prep::{highpass, highpass_buffer_len};
use orbfix::matcher::Grid;
use orbfix::nn::model::{Arena, SiameseNet, EMBED_LEN, SHIPPED_WEIGHTS, SPEC};
use orbfix::nn::weights::{crc32, parse, WeightsError};
use orbfix::reproject::{reproject_top_down, table_len, Cell, GridSpec, Tap};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A runner with `cases` cases from a fixed seed.
fn runner(cases: u32) -> TestRunner {
    let cfg = Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    };
    TestRunner::new_with_rng(cfg, TestRng::from_seed(RngAlgorithm::ChaCha, &[7; 32]))
}

fn report(name: &str, n: &AtomicUsize) {
    println!("{name}: {} inputs, 0 crashes", n.load(Ordering::Relaxed));
}

/// Any f32, with NaN, infinities, zeros and huge values well represented.
fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(f32::NEG_INFINITY),
        Just(0.0f32),
        Just(-0.0f32),
        Just(f32::MAX),
        Just(f32::MIN_POSITIVE),
        -1e3f32..1e3f32,
        any::<f32>(),
    ]
}

fn with_crc(mut b: Vec<u8>) -> Vec<u8> {
    let n = b.len();
    if n >= 4 {
        let c = crc32(&b[..n - 4]).to_le_bytes();
        b[n - 4..].copy_from_slice(&c);
    }
    b
}

#[test]
fn weight_parser_never_panics_and_catches_every_mutation() {
    let n = AtomicUsize::new(0);
    // Arbitrary bytes, with and without a valid CRC trailer and the right magic.
    runner(3000)
        .run(
            &(
                prop::collection::vec(any::<u8>(), 0..400),
                any::<bool>(),
                any::<bool>(),
            ),
            |(mut b, magic, crc)| {
                if magic && b.len() >= 4 {
                    b[..4].copy_from_slice(b"OFW1");
                }
                let b = if crc { with_crc(b) } else { b };
                n.fetch_add(1, Ordering::Relaxed);
                prop_assert!(parse(&b, &SPEC).is_err());
                Ok(())
            },
        )
        .unwrap();
    // Mutations of the shipped file: 1-8 bytes replaced. Without a new CRC every real change
    // is detected; with a recomputed CRC the structure and range checks must hold, and any
    // file they accept must embed extreme inputs without an overflow (dev profile).
    let len = SHIPPED_WEIGHTS.len();
    runner(1500)
        .run(
            &(
                prop::collection::vec((0..len, any::<u8>()), 1..8),
                any::<bool>(),
                any::<i8>(),
            ),
            |(muts, recrc, fill)| {
                let mut b = SHIPPED_WEIGHTS.to_vec();
                for &(p, v) in &muts {
                    b[p] = v;
                }
                n.fetch_add(1, Ordering::Relaxed);
                let changed = b != SHIPPED_WEIGHTS;
                if !recrc {
                    let r = parse(&b, &SPEC);
                    if changed {
                        prop_assert!(
                            matches!(r, Err(WeightsError::CrcMismatch { .. })),
                            "undetected mutation {muts:?}: {:?}",
                            r.err()
                        );
                    } else {
                        prop_assert!(r.is_ok());
                    }
                    return Ok(());
                }
                let b = with_crc(b);
                if let Ok(net) = SiameseNet::from_bytes(&b) {
                    let input = [fill; orbfix::nn::input::INPUT_LEN];
                    let mut out = [0i8; EMBED_LEN];
                    let mut arena = Box::new(Arena::new());
                    prop_assert!(net.embed(&input, &mut arena, &mut out).is_ok());
                }
                Ok(())
            },
        )
        .unwrap();
    // Biases anywhere in i32 with a valid CRC: accepted files embed without overflow.
    runner(300)
        .run(
            &(0..SPEC.len(), 0..16usize, any::<i32>(), any::<i8>()),
            |(layer, ch, bias, fill)| {
                let mut m =
                    orbfix_host::nn::qmodel::HostQModel::from_bytes(SHIPPED_WEIGHTS).unwrap();
                m.layers[layer].bias[ch] = bias;
                let b = m.to_bytes();
                n.fetch_add(1, Ordering::Relaxed);
                match SiameseNet::from_bytes(&b) {
                    Ok(net) => {
                        let input = [fill; orbfix::nn::input::INPUT_LEN];
                        let mut out = [0i8; EMBED_LEN];
                        let mut arena = Box::new(Arena::new());
                        prop_assert!(net.embed(&input, &mut arena, &mut out).is_ok());
                    }
                    Err(e) => prop_assert!(
                        matches!(e, WeightsError::AccumulatorOverflow { .. }),
                        "{e:?}"
                    ),
                }
                Ok(())
            },
        )
        .unwrap();
    report("weight parser", &n);
}

#[test]
fn reproject_never_panics_on_hostile_parameters() {
    let n = AtomicUsize::new(0);
    let params = (0u32..40, 0u32..40, any_f32(), any_f32(), any_f32());
    let pose = (
        any_f32(),
        any_f32(),
        any_f32(),
        any_f32(),
        any_f32(),
        any_f32(),
    );
    let grid = (0usize..48, any_f32(), any_f32());
    // Frame size and stride of each view, or no frame.
    let frame = prop::option::of((0usize..40, 0usize..40, 0usize..8));
    runner(1500)
        .run(
            &(
                params,
                pose,
                grid,
                [frame.clone(), frame.clone(), frame.clone(), frame],
                any::<u8>(),
            ),
            |((w, h, hfov, height, tilt), (x, y, z, hd, pi, ro), (gn, gm, gr), frames, fillv)| {
                let params = CameraParams {
                    width_px: w,
                    height_px: h,
                    hfov_deg: hfov,
                    height_m: height,
                    tilt_deg: tilt,
                };
                let pose = RoverPose {
                    x_m: x,
                    y_m: y,
                    ground_z_m: z,
                    heading_deg: hd,
                    pitch_deg: pi,
                    roll_deg: ro,
                };
                let grid = GridSpec {
                    n: gn,
                    m_per_px: gm,
                    max_range_m: gr,
                };
                type Frame = (Vec<u8>, usize, usize, usize);
                let bufs: Vec<Option<Frame>> = frames
                    .iter()
                    .map(|f| {
                        f.map(|(fw, fh, extra)| {
                            let stride = fw + extra;
                            (vec![fillv; stride * fh], fw, fh, stride)
                        })
                    })
                    .collect();
                let views: Vec<Option<ImageView<'_>>> = bufs
                    .iter()
                    .map(|b| {
                        b.as_ref()
                            .and_then(|(d, fw, fh, s)| ImageView::with_stride(d, *fw, *fh, *s).ok())
                    })
                    .collect();
                let views = [views[0], views[1], views[2], views[3]];
                let cells_n = table_len(gn);
                let mut cells = vec![Cell::EMPTY; cells_n];
                let mut extra = vec![Tap::EMPTY; 64];
                let mut out = vec![0u8; gn * gn];
                let mut mask = vec![0u8; gn * gn];
                n.fetch_add(1, Ordering::Relaxed);
                if let Ok(rep) = reproject_top_down(
                    &views, &params, &pose, &grid, &mut cells, &mut extra, &mut out, &mut mask,
                ) {
                    prop_assert!(rep.valid_cells <= gn * gn);
                    prop_assert!(mask.iter().all(|&m| m == 0 || m == 255));
                    prop_assert_eq!(mask.iter().filter(|&&m| m == 255).count(), rep.valid_cells);
                }
                Ok(())
            },
        )
        .unwrap();
    report("reproject", &n);
}

#[test]
fn image_grid_and_georef_constructors_hold_their_invariants() {
    let n = AtomicUsize::new(0);
    let size = prop_oneof![0usize..20, Just(usize::MAX), any::<usize>()];
    runner(3000)
        .run(
            &(
                0usize..300,
                size.clone(),
                size.clone(),
                size.clone(),
                (size.clone(), size.clone(), size.clone(), size.clone()),
            ),
            |(len, w, h, stride, (sx, sy, sw, sh))| {
                let data = vec![7u8; len];
                n.fetch_add(1, Ordering::Relaxed);
                if let Ok(v) = ImageView::with_stride(&data, w, h, stride) {
                    prop_assert!(w >= 1 && h >= 1 && stride >= w);
                    prop_assert!(v.row(h - 1).is_some_and(|r| r.len() == w));
                    prop_assert!(v.row(h).is_none());
                    if let Some(s) = v.sub(sx, sy, sw, sh) {
                        prop_assert!(sx.checked_add(sw).is_some_and(|e| e <= w));
                        prop_assert!(sy.checked_add(sh).is_some_and(|e| e <= h));
                        prop_assert!(s.row(sh - 1).is_some_and(|r| r.len() == sw));
                    }
                }
                Ok(())
            },
        )
        .unwrap();
    runner(3000)
        .run(
            &(size.clone(), size.clone(), size.clone(), size.clone(), size),
            |(tw, th, rw, rh, step)| {
                n.fetch_add(1, Ordering::Relaxed);
                if let Ok(g) = Grid::new(tw, th, rw, rh, step) {
                    prop_assert!(g.cols() >= 1 && g.rows() >= 1 && g.step() == step);
                    prop_assert_eq!(g.cols().checked_mul(g.rows()), Some(g.len()));
                }
                Ok(())
            },
        )
        .unwrap();
    runner(3000)
        .run(&(any_f32(), any_f32(), any_f32()), |(x, y, r)| {
            n.fetch_add(1, Ordering::Relaxed);
            match GeoRef::new(x, y, r) {
                Ok(g) => {
                    prop_assert!(g.m_per_px().is_finite() && g.m_per_px() > 0.0);
                    prop_assert!(g.origin_x_m().abs() <= MAX_ORIGIN_M);
                    prop_assert!(g.origin_y_m().abs() <= MAX_ORIGIN_M);
                }
                Err(_) => {
                    let ok = |v: f32| v.is_finite() && v.abs() <= MAX_ORIGIN_M;
                    prop_assert!(!(r.is_finite() && r > 0.0 && ok(x) && ok(y)));
                }
            }
            Ok(())
        })
        .unwrap();
    report("ImageView / Grid / GeoRef constructors", &n);
}

#[test]
fn highpass_never_panics_and_huge_radii_are_the_whole_image() {
    let n = AtomicUsize::new(0);
    let radius = prop_oneof![0usize..8, Just(usize::MAX), any::<usize>()];
    runner(600)
        .run(
            &(
                1usize..24,
                1usize..24,
                radius,
                any::<bool>(),
                prop::collection::vec(any::<u8>(), 24 * 24 * 2),
            ),
            |(w, h, r, masked, bytes)| {
                let (img, m) = bytes.split_at(24 * 24);
                let src = ImageView::new(&img[..w * h], w, h).unwrap();
                let mv = ImageView::new(&m[..w * h], w, h).unwrap();
                let mask = masked.then_some(&mv);
                let mut out = vec![0u8; w * h];
                let mut o = ImageViewMut::new(&mut out, w, h).unwrap();
                let mut scratch = vec![0u32; highpass_buffer_len(w)];
                n.fetch_add(1, Ordering::Relaxed);
                highpass(&src, mask, r, &mut o, &mut scratch).unwrap();
                // A radius at or beyond the image is the same box: the whole image.
                let mut whole = vec![0u8; w * h];
                let mut ow = ImageViewMut::new(&mut whole, w, h).unwrap();
                highpass(&src, mask, r.min(w.max(h)), &mut ow, &mut scratch).unwrap();
                prop_assert_eq!(&out, &whole);
                // A short scratch is a typed error.
                let mut o = ImageViewMut::new(&mut whole, w, h).unwrap();
                let short = highpass_buffer_len(w) - 1;
                prop_assert!(highpass(&src, mask, r, &mut o, &mut scratch[..short]).is_err());
                Ok(())
            },
        )
        .unwrap();
    report("highpass", &n);
}
