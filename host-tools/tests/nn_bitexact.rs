//! The core's int8 kernels and network against the host's independent quantized reference,
//! bit for bit, on random tensors and random quantization parameters.

use orbfix::nn::conv::{conv2d_s8, conv2d_s8_buffer_size, ConvParams, Dims};
use orbfix::nn::dense::{dense_s8, DenseParams};
use orbfix::nn::input::INPUT_LEN;
use orbfix::nn::model::{Arena, SiameseNet, EMBED_LEN, SPEC};
use orbfix::nn::weights::LayerKind;
use orbfix_host::nn::qmodel::{HostQLayer, HostQModel};
use orbfix_host::nn::reference;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

#[allow(clippy::too_many_arguments)]
fn random_layer(
    rng: &mut StdRng,
    kind: u8,
    kernel: usize,
    stride: usize,
    pad: usize,
    relu: bool,
    (in_h, in_w, in_c): (usize, usize, usize),
    out_c: usize,
    input_zp: i32,
) -> HostQLayer {
    let output_zp = if relu {
        -128
    } else {
        rng.random_range(-20..20)
    };
    let n = out_c * kernel * kernel * in_c;
    HostQLayer {
        kind,
        kernel,
        stride,
        pad,
        relu,
        in_h,
        in_w,
        in_c,
        out_c,
        input_zp,
        output_zp,
        act_min: if relu { output_zp } else { -128 },
        act_max: 127,
        output_scale: 0.05,
        weight_scale: vec![0.01; out_c],
        bias: (0..out_c).map(|_| rng.random_range(-5000..5000)).collect(),
        // Realistic multipliers: accumulators of a few thousand land in int8 range, with
        // plenty of exact rounding ties and saturation at both ends.
        multiplier: (0..out_c)
            .map(|_| rng.random_range(1 << 30..i32::MAX))
            .collect(),
        shift: (0..out_c).map(|_| rng.random_range(-12..=-4)).collect(),
        weights: (0..n).map(|_| rng.random_range(-127..=127)).collect(),
    }
}

fn random_model(seed: u64) -> HostQModel {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut zp = 0;
    let mut layers = Vec::new();
    for s in SPEC.iter() {
        let kind = match s.kind {
            LayerKind::Conv => 1,
            LayerKind::DensePerPixel => 2,
        };
        let l = random_layer(
            &mut rng,
            kind,
            s.kernel,
            s.stride,
            s.pad,
            s.relu,
            (s.in_h, s.in_w, s.in_c),
            s.out_c,
            zp,
        );
        zp = l.output_zp;
        layers.push(l);
    }
    HostQModel {
        input_scale: 1.0 / 32.0,
        input_zp: 0,
        layers,
    }
}

#[test]
fn conv_kernel_matches_reference_on_random_geometries() {
    let mut rng = StdRng::seed_from_u64(11);
    let mut varied = 0;
    for case in 0..40 {
        let kernel = [1, 3, 5][case % 3];
        let stride = 1 + case % 2;
        let pad = (case / 2) % 3;
        let (h, w, c) = (
            rng.random_range(kernel..12),
            rng.random_range(kernel..12),
            rng.random_range(1..9),
        );
        let oc = rng.random_range(1..9);
        let zp_in = rng.random_range(-128..128);
        let l = random_layer(
            &mut rng,
            1,
            kernel,
            stride,
            pad,
            case % 4 == 0,
            (h, w, c),
            oc,
            zp_in,
        );
        let input: Vec<i8> = (0..h * w * c).map(|_| rng.random()).collect();
        let want = reference::run_layer(&l, &input);
        let out_dims = Dims {
            h: l.out_h(),
            w: l.out_w(),
            c: oc,
        };
        let mut got = vec![0i8; out_dims.len()];
        let mut scratch = vec![0i16; conv2d_s8_buffer_size(kernel, c)];
        let shift: Vec<i32> = l.shift.iter().map(|&s| s as i32).collect();
        conv2d_s8(
            &ConvParams {
                kernel,
                stride,
                pad,
                input_offset: -zp_in,
                output_offset: l.output_zp,
                act_min: l.act_min,
                act_max: l.act_max,
            },
            &input,
            Dims { h, w, c },
            &l.weights,
            &l.bias,
            &l.multiplier,
            &shift,
            &mut got,
            out_dims,
            &mut scratch,
        )
        .unwrap();
        assert_eq!(
            got, want,
            "case {case}: k{kernel} s{stride} p{pad} {h}x{w}x{c}->{oc}"
        );
        varied += got.iter().any(|&v| v != got[0]) as usize;
    }
    // Most outputs are not degenerate (the comparison could fail).
    assert!(varied >= 30, "only {varied} of 40 cases had varied outputs");
}

#[test]
fn conv_kernel_rejects_bad_buffers() {
    let p = ConvParams {
        kernel: 3,
        stride: 1,
        pad: 1,
        input_offset: 0,
        output_offset: 0,
        act_min: -128,
        act_max: 127,
    };
    let d = Dims { h: 4, w: 4, c: 2 };
    let mut out = vec![0i8; 32];
    let mut scratch = vec![0i16; 17];
    let r = conv2d_s8(
        &p,
        &[0; 32],
        d,
        &[0; 36],
        &[0; 2],
        &[1 << 30; 2],
        &[0; 2],
        &mut out,
        d,
        &mut scratch,
    );
    assert_eq!(r, Err(orbfix::nn::NnError::ScratchTooSmall));
    let mut scratch = vec![0i16; 18];
    let r = conv2d_s8(
        &p,
        &[0; 31],
        d,
        &[0; 36],
        &[0; 2],
        &[1 << 30; 2],
        &[0; 2],
        &mut out,
        d,
        &mut scratch,
    );
    assert_eq!(r, Err(orbfix::nn::NnError::BufferSize));
    let bad = Dims { h: 3, w: 4, c: 2 };
    let r = conv2d_s8(
        &p,
        &[0; 32],
        d,
        &[0; 36],
        &[0; 2],
        &[1 << 30; 2],
        &[0; 2],
        &mut out,
        bad,
        &mut scratch,
    );
    assert_eq!(r, Err(orbfix::nn::NnError::BadGeometry));
}

#[test]
fn dense_kernel_matches_reference() {
    let mut rng = StdRng::seed_from_u64(12);
    for case in 0..10 {
        let (rows, inf, outf) = (
            rng.random_range(1..20),
            rng.random_range(1..70),
            rng.random_range(1..40),
        );
        let zp_in = rng.random_range(-128..128);
        let l = random_layer(&mut rng, 2, 1, 1, 0, false, (rows, 1, inf), outf, zp_in);
        let input: Vec<i8> = (0..rows * inf).map(|_| rng.random()).collect();
        let want = reference::run_layer(&l, &input);
        let mut got = vec![0i8; rows * outf];
        let shift: Vec<i32> = l.shift.iter().map(|&s| s as i32).collect();
        dense_s8(
            &DenseParams {
                input_offset: -zp_in,
                output_offset: l.output_zp,
                act_min: l.act_min,
                act_max: l.act_max,
            },
            rows,
            inf,
            outf,
            &input,
            &l.weights,
            &l.bias,
            &l.multiplier,
            &shift,
            &mut got,
        )
        .unwrap();
        assert_eq!(got, want, "case {case}");
    }
}

#[test]
fn network_matches_reference_bit_for_bit() {
    for seed in 0..3u64 {
        let m = random_model(seed);
        let bytes = m.to_bytes();
        let net = SiameseNet::from_bytes(&bytes).expect("core accepts the random model");
        let mut arena = Box::new(Arena::new());
        let mut rng = StdRng::seed_from_u64(100 + seed);
        for _ in 0..2 {
            let mut input = [0i8; INPUT_LEN];
            input
                .iter_mut()
                .for_each(|v| *v = rng.random_range(-127..=127));
            let mut got = [0i8; EMBED_LEN];
            net.embed(&input, &mut arena, &mut got).unwrap();
            let want = reference::run(&m, &input, None);
            assert_eq!(&got[..], &want[..], "seed {seed}");
            assert!(got.iter().any(|&v| v != got[0]), "degenerate embedding");
        }
        // The host reader round-trips the file.
        assert_eq!(HostQModel::from_bytes(&bytes).unwrap(), m);
    }
}

#[test]
fn shipped_network_matches_reference() {
    let net = orbfix::nn::model::shipped().expect("the shipped weights are valid");
    let m = HostQModel::from_bytes(orbfix::nn::model::SHIPPED_WEIGHTS).unwrap();
    let mut rng = StdRng::seed_from_u64(5);
    let mut input = [0i8; INPUT_LEN];
    input
        .iter_mut()
        .for_each(|v| *v = rng.random_range(-100..=100));
    let mut got = [0i8; EMBED_LEN];
    net.embed(&input, &mut Box::new(Arena::new()), &mut got)
        .unwrap();
    assert_eq!(&got[..], &reference::run(&m, &input, None)[..]);
}
