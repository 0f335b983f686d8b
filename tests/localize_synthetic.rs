//! Localization on synthetic textures: the template is cut from the map at a known place
//! (with holes, gain/offset and noise), so the right answer is known exactly.

use orbfix::geo::GeoRef;
use orbfix::image::ImageView;
use orbfix::localize::{
    buffer_sizes, localize, nearest_window, rank_of, window_search, LocalizeConfig, LocalizeError,
};
use orbfix::matcher::{l1::L1, l2::L2, ncc::Ncc, MatchError, Matcher, OpCounts};

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> u32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 33) as u32
    }
    fn unit(&mut self) -> f32 {
        (self.next() % 10_000) as f32 / 10_000.0
    }
}

/// Two-octave value noise, `w x h`, values 0..255.
fn texture(w: usize, h: usize, seed: u64) -> Vec<u8> {
    let mut rng = Lcg(seed);
    let mut out = vec![0f32; w * h];
    for (cell, amp) in [(16usize, 0.6f32), (5, 0.4)] {
        let gw = w / cell + 2;
        let gh = h / cell + 2;
        let g: Vec<f32> = (0..gw * gh).map(|_| rng.unit()).collect();
        for y in 0..h {
            for x in 0..w {
                let (fx, fy) = (x as f32 / cell as f32, y as f32 / cell as f32);
                let (ix, iy) = (fx as usize, fy as usize);
                let (tx, ty) = (fx - ix as f32, fy - iy as f32);
                let v = |i: usize, j: usize| g[j * gw + i];
                let a = v(ix, iy) * (1.0 - tx) + v(ix + 1, iy) * tx;
                let b = v(ix, iy + 1) * (1.0 - tx) + v(ix + 1, iy + 1) * tx;
                out[y * w + x] += amp * (a * (1.0 - ty) + b * ty);
            }
        }
    }
    out.iter()
        .map(|v| (v * 255.0).clamp(0.0, 255.0) as u8)
        .collect()
}

const MW: usize = 600;
const TW: usize = 100;

fn cfg() -> LocalizeConfig {
    LocalizeConfig {
        coarse_factor: 4,
        fine_factor: 2,
        ..LocalizeConfig::default()
    }
}

/// Template cut at top-left `(x0, y0)` with a hole wedge, gain 0.8, offset +20, noise.
fn cut(map: &[u8], x0: usize, y0: usize, seed: u64) -> (Vec<u8>, Vec<u8>) {
    let mut rng = Lcg(seed);
    let mut t = vec![0u8; TW * TW];
    let mut w = vec![0u8; TW * TW];
    for y in 0..TW {
        for x in 0..TW {
            let v = map[(y0 + y) * MW + x0 + x] as f32 * 0.8 + 20.0 + (rng.unit() - 0.5) * 20.0;
            t[y * TW + x] = v.clamp(0.0, 255.0) as u8;
            // Hole: a band near the centre and the north-east corner, as cameras leave.
            let hole = (x as i32 - 50).abs() < 6 && (y as i32 - 50).abs() < 6 || x + (TW - y) < 30;
            w[y * TW + x] = if hole { 0 } else { 255 };
        }
    }
    (t, w)
}

fn run<M: Matcher>(
    m: &M,
    map: &[u8],
    t: &[u8],
    w: &[u8],
    geo: &GeoRef,
    prior: (f32, f32),
) -> Result<orbfix::localize::Fix, LocalizeError> {
    let (nb, nf) = buffer_sizes(TW, TW, MW, MW, &cfg()).unwrap();
    let mut bytes = vec![0u8; nb];
    let mut floats = vec![0f32; nf];
    localize(
        m,
        &ImageView::new(t, TW, TW).unwrap(),
        &ImageView::new(w, TW, TW).unwrap(),
        geo.m_per_px(),
        &ImageView::new(map, MW, MW).unwrap(),
        geo,
        prior.0,
        prior.1,
        &cfg(),
        &mut bytes,
        &mut floats,
    )
}

#[test]
fn ncc_finds_the_cut_within_a_pixel() {
    let map = texture(MW, MW, 7);
    let geo = GeoRef::new(1000.0, 2000.0, 0.5).unwrap();
    for (k, &(x0, y0)) in [(123usize, 341usize), (400, 57), (250, 250)]
        .iter()
        .enumerate()
    {
        let (t, w) = cut(&map, x0, y0, k as u64);
        let truth = geo.to_world(x0 as f32 + 50.0, y0 as f32 + 50.0);
        let fix = run(&Ncc::default(), &map, &t, &w, &geo, (1150.0, 1850.0)).unwrap();
        let err = ((fix.x_m - truth.0).powi(2) + (fix.y_m - truth.1).powi(2)).sqrt();
        assert!(err < 0.5, "cut {k}: error {err} m, fix {fix:?}");
        assert!(!fix.on_border);
        assert!(fix.confidence > 0.3, "confidence {}", fix.confidence);
        assert!(fix.ops_coarse.macs > 0 && fix.ops_fine.macs > 0);
        assert!(fix.candidates[0].refined);
    }
}

#[test]
fn subpixel_offset_is_recovered() {
    // A map shifted by half a pixel: block-average neighbours so the truth is at +0.5 px.
    let base = texture(MW + 1, MW, 11);
    let map: Vec<u8> = (0..MW * MW)
        .map(|i| {
            let (x, y) = (i % MW, i / MW);
            (base[y * (MW + 1) + x] as u16 + base[y * (MW + 1) + x + 1] as u16).div_ceil(2) as u8
        })
        .collect();
    let geo = GeoRef::new(0.0, 0.0, 1.0).unwrap();
    // Template from the unshifted texture at column 200 lies at map column 199.5.
    let mut t = vec![0u8; TW * TW];
    for y in 0..TW {
        for x in 0..TW {
            t[y * TW + x] = base[(300 + y) * (MW + 1) + 200 + x];
        }
    }
    let w = vec![255u8; TW * TW];
    let fix = run(&Ncc::default(), &map, &t, &w, &geo, (300.0, -300.0)).unwrap();
    let truth_x = 199.5 + 50.0;
    assert!(
        (fix.x_m - truth_x).abs() < 0.6,
        "x {} vs {truth_x}",
        fix.x_m
    );
    assert!((fix.y_m + 350.0).abs() < 0.6, "y {}", fix.y_m);
}

#[test]
fn window_search_ranks_true_window_first_for_all_matchers() {
    let map = texture(MW, MW, 3);
    let geo = GeoRef::new(0.0, 0.0, 0.5).unwrap();
    // 600 px map, 100 px windows, stride 25 -> 21 x 21 = 441 windows like the study.
    let (x0, y0) = (275usize, 150usize);
    let (t, w) = cut(&map, x0, y0, 5);
    let matchers: [&dyn Matcher; 3] = [&L1, &L2, &Ncc::default()];
    for m in matchers {
        let mut scores = [0f32; 441];
        let mut ops = OpCounts::default();
        let g = window_search(
            m,
            &ImageView::new(&t, TW, TW).unwrap(),
            &ImageView::new(&w, TW, TW).unwrap(),
            &ImageView::new(&map, MW, MW).unwrap(),
            25,
            &mut scores,
            &mut ops,
        )
        .unwrap();
        assert_eq!(g.len(), 441);
        assert_eq!(ops.windows, 441);
        let (tx, ty) = geo.to_world(x0 as f32 + 50.0, y0 as f32 + 50.0);
        let idx = nearest_window(&g, &geo, TW, TW, tx, ty);
        assert_eq!(idx, 6 * 21 + 11);
        // NCC is gain/offset invariant; L1/L2 are not, but the cut is still closest.
        let rank = rank_of(&scores, idx).unwrap();
        assert_eq!(rank, 0, "{}: rank {rank}", m.name());
    }
}

#[test]
fn flat_map_gives_low_confidence() {
    let map = vec![90u8; MW * MW];
    let tex = texture(MW, MW, 9);
    let (t, w) = cut(&tex, 100, 100, 1);
    let geo = GeoRef::new(0.0, 0.0, 0.5).unwrap();
    let fix = run(&Ncc::default(), &map, &t, &w, &geo, (150.0, -150.0)).unwrap();
    assert_eq!(fix.confidence, 0.0, "{fix:?}");
    // Nearly flat map (1-grey-level noise): still not confident.
    let mut rng = Lcg(4);
    let noisy: Vec<u8> = (0..MW * MW).map(|_| 90 + (rng.next() % 2) as u8).collect();
    let fix = run(&Ncc::default(), &noisy, &t, &w, &geo, (150.0, -150.0)).unwrap();
    assert!(fix.confidence < 0.2, "{}", fix.confidence);
}

#[test]
fn bad_inputs_are_typed_errors() {
    let map = texture(MW, MW, 1);
    let geo = GeoRef::new(0.0, 0.0, 0.5).unwrap();
    let (t, w) = cut(&map, 10, 10, 1);
    // Prior outside the map.
    assert_eq!(
        run(&Ncc::default(), &map, &t, &w, &geo, (-5.0, 10.0)).err(),
        Some(LocalizeError::PriorOutsideMap)
    );
    assert_eq!(
        run(&Ncc::default(), &map, &t, &w, &geo, (f32::NAN, -1.0)).err(),
        Some(LocalizeError::PriorOutsideMap)
    );
    // All "no data".
    let zero = vec![0u8; TW * TW];
    assert_eq!(
        run(&Ncc::default(), &map, &t, &zero, &geo, (10.0, -10.0)).err(),
        Some(LocalizeError::Match(MatchError::NoValidPixels))
    );
    // A sliver of data.
    let mut sliver = zero.clone();
    sliver[..100].fill(255);
    assert!(matches!(
        run(&Ncc::default(), &map, &t, &sliver, &geo, (10.0, -10.0)),
        Err(LocalizeError::TooLittleCoverage { permille: 10 })
    ));
    // Featureless top-down image.
    let flat = vec![100u8; TW * TW];
    assert_eq!(
        run(&Ncc::default(), &map, &flat, &w, &geo, (10.0, -10.0)).err(),
        Some(LocalizeError::Match(MatchError::FeaturelessTemplate))
    );
    // Resolution mismatch.
    let (nb, nf) = buffer_sizes(TW, TW, MW, MW, &cfg()).unwrap();
    let (mut b, mut f) = (vec![0u8; nb], vec![0f32; nf]);
    let r = localize(
        &Ncc::default(),
        &ImageView::new(&t, TW, TW).unwrap(),
        &ImageView::new(&w, TW, TW).unwrap(),
        0.25,
        &ImageView::new(&map, MW, MW).unwrap(),
        &geo,
        10.0,
        -10.0,
        &cfg(),
        &mut b,
        &mut f,
    );
    assert!(matches!(r, Err(LocalizeError::ResolutionMismatch { .. })));
    // Scratch too small.
    let r = localize(
        &Ncc::default(),
        &ImageView::new(&t, TW, TW).unwrap(),
        &ImageView::new(&w, TW, TW).unwrap(),
        0.5,
        &ImageView::new(&map, MW, MW).unwrap(),
        &geo,
        10.0,
        -10.0,
        &cfg(),
        &mut b[..nb - 1],
        &mut f,
    );
    assert_eq!(r.err(), Some(LocalizeError::ScratchTooSmall));
    // Template not a multiple of the coarse factor.
    assert_eq!(
        buffer_sizes(
            98,
            98,
            MW,
            MW,
            &LocalizeConfig {
                coarse_factor: 8,
                ..cfg()
            }
        ),
        Err(LocalizeError::BadConfig)
    );
}
