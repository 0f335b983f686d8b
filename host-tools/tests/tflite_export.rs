//! `orbfix export-tflite`'s model read back from its flatbuffer bytes: structure, constant
//! data, and its outputs under TFLite semantics (SAME/VALID/PAD geometry, multipliers derived
//! from the tensors' scales as TFLite derives them) equal to the core's, bit for bit.
//! (`scripts/tflm-check.sh` runs the same model in TensorFlow Lite Micro itself.)

use orbfix::nn::conv::{conv2d_s8, conv2d_s8_buffer_size, ConvParams, Dims};
use orbfix::nn::input::INPUT_LEN;
use orbfix::nn::model::{Arena, SiameseNet, EMBED_LEN, SHIPPED_WEIGHTS};
use orbfix_host::nn::multiplier::tflite_multiplier;
use orbfix_host::nn::qmodel::HostQModel;
use orbfix_host::tflite::export::export;
use orbfix_host::tflite::padding::same_geometry;
use orbfix_host::tflite::schema_generated::tflite;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

fn shipped_model() -> Vec<u8> {
    export(
        &HostQModel::from_bytes(SHIPPED_WEIGHTS).unwrap(),
        "test",
        false,
    )
    .unwrap()
}

/// An int8 NHWC activation with its quantization.
#[derive(Clone)]
struct Act {
    dims: Dims,
    data: Vec<i8>,
    scale: f32,
    zp: i32,
}

fn quant(t: &tflite::Tensor) -> (Vec<f32>, Vec<i64>) {
    let q = t.quantization().unwrap();
    (
        q.scale().unwrap().iter().collect(),
        q.zero_point().unwrap().iter().collect(),
    )
}

fn dims4(t: &tflite::Tensor) -> Dims {
    let s: Vec<i32> = t.shape().unwrap().iter().collect();
    assert_eq!(s.len(), 4);
    assert_eq!(s[0], 1);
    Dims {
        h: s[1] as usize,
        w: s[2] as usize,
        c: s[3] as usize,
    }
}

fn pad(a: &Act, top: usize, bottom: usize, left: usize, right: usize, value: i32) -> Act {
    let d = Dims {
        h: a.dims.h + top + bottom,
        w: a.dims.w + left + right,
        c: a.dims.c,
    };
    let mut data = vec![value as i8; d.len()];
    for y in 0..a.dims.h {
        for x in 0..a.dims.w {
            for c in 0..a.dims.c {
                data[((y + top) * d.w + x + left) * d.c + c] =
                    a.data[(y * a.dims.w + x) * a.dims.c + c];
            }
        }
    }
    Act {
        dims: d,
        data,
        ..*a
    }
}

/// Runs the model's one subgraph on `input` with TFLite's operator semantics.
fn run_tflite(model: &[u8], input: &[i8]) -> Vec<i8> {
    let m = tflite::root_as_model(model).unwrap();
    let codes: Vec<_> = m
        .operator_codes()
        .unwrap()
        .iter()
        .map(|c| c.builtin_code())
        .collect();
    let buffers = m.buffers().unwrap();
    let g = m.subgraphs().unwrap().get(0);
    let tensors = g.tensors().unwrap();
    let data = |i: i32| -> Vec<u8> {
        let t = tensors.get(i as usize);
        buffers
            .get(t.buffer() as usize)
            .data()
            .unwrap()
            .iter()
            .collect()
    };
    let i32s = |b: Vec<u8>| -> Vec<i32> {
        b.chunks_exact(4)
            .map(|c| i32::from_le_bytes(c.try_into().unwrap()))
            .collect()
    };
    let input_t = tensors.get(g.inputs().unwrap().get(0) as usize);
    let (s, z) = quant(&input_t);
    let mut acts = std::collections::HashMap::new();
    acts.insert(
        g.inputs().unwrap().get(0),
        Act {
            dims: dims4(&input_t),
            data: input.to_vec(),
            scale: s[0],
            zp: z[0] as i32,
        },
    );
    for op in g.operators().unwrap() {
        let ins: Vec<i32> = op.inputs().unwrap().iter().collect();
        let out_i = op.outputs().unwrap().get(0);
        let out_t = tensors.get(out_i as usize);
        let (os, oz) = quant(&out_t);
        let x: Act = acts[&ins[0]].clone();
        let code = codes[op.opcode_index() as usize];
        let y = if code == tflite::BuiltinOperator::PAD {
            let p = i32s(data(ins[1]));
            assert_eq!((p[0], p[1], p[6], p[7]), (0, 0, 0, 0));
            // int8 PAD fills with the output zero point.
            pad(
                &x,
                p[2] as usize,
                p[3] as usize,
                p[4] as usize,
                p[5] as usize,
                oz[0] as i32,
            )
        } else {
            assert_eq!(code, tflite::BuiltinOperator::CONV_2D);
            let o = op.builtin_options_as_conv_2_doptions().unwrap();
            assert_eq!((o.dilation_h_factor(), o.dilation_w_factor()), (1, 1));
            let stride = o.stride_h() as usize;
            assert_eq!(o.stride_w() as usize, stride);
            let wt = tensors.get(ins[1] as usize);
            let k = dims4_ohwi(&wt);
            let x = if o.padding() == tflite::Padding::SAME {
                let out_dims = dims4(&out_t);
                let (oh, top) = same_geometry(x.dims.h, k, stride);
                let (ow, left) = same_geometry(x.dims.w, k, stride);
                assert_eq!((oh, ow), (out_dims.h, out_dims.w));
                let bottom = ((oh - 1) * stride + k).saturating_sub(x.dims.h) - top;
                let right = ((ow - 1) * stride + k).saturating_sub(x.dims.w) - left;
                pad(&x, top, bottom, left, right, x.zp)
            } else {
                x
            };
            let (ws, wz) = quant(&wt);
            assert!(wz.iter().all(|&z| z == 0));
            let weights: Vec<i8> = data(ins[1]).iter().map(|&v| v as i8).collect();
            let bias = i32s(data(ins[2]));
            let (mult, shift): (Vec<i32>, Vec<i32>) = ws
                .iter()
                .map(|&sw| {
                    let (m, s) = tflite_multiplier(x.scale, sw, os[0]);
                    (m, s as i32)
                })
                .unzip();
            let relu = o.fused_activation_function() == tflite::ActivationFunctionType::RELU;
            let out_dims = dims4(&out_t);
            let mut out = vec![0i8; out_dims.len()];
            let mut scratch = vec![0i16; conv2d_s8_buffer_size(k, x.dims.c)];
            conv2d_s8(
                &ConvParams {
                    kernel: k,
                    stride,
                    pad: 0,
                    input_offset: -x.zp,
                    output_offset: oz[0] as i32,
                    act_min: if relu { oz[0] as i32 } else { -128 },
                    act_max: 127,
                },
                &x.data,
                x.dims,
                &weights,
                &bias,
                &mult,
                &shift,
                &mut out,
                out_dims,
                &mut scratch,
            )
            .unwrap();
            Act {
                dims: out_dims,
                data: out,
                scale: os[0],
                zp: oz[0] as i32,
            }
        };
        assert_eq!(y.dims, dims4(&out_t));
        acts.insert(out_i, y);
    }
    acts[&g.outputs().unwrap().get(0)].data.clone()
}

/// Kernel side of an OHWI weight tensor (square kernels).
fn dims4_ohwi(t: &tflite::Tensor) -> usize {
    let s: Vec<i32> = t.shape().unwrap().iter().collect();
    assert_eq!(s[1], s[2]);
    s[1] as usize
}

#[test]
fn structure_and_constants_are_the_weight_file() {
    let bytes = shipped_model();
    assert!(tflite::model_buffer_has_identifier(&bytes));
    let q = HostQModel::from_bytes(SHIPPED_WEIGHTS).unwrap();
    let m = tflite::root_as_model(&bytes).unwrap();
    assert_eq!(m.version(), 3);
    let codes: Vec<_> = m
        .operator_codes()
        .unwrap()
        .iter()
        .map(|c| c.builtin_code())
        .collect();
    let g = m.subgraphs().unwrap().get(0);
    let ops: Vec<_> = g
        .operators()
        .unwrap()
        .iter()
        .map(|o| codes[o.opcode_index() as usize])
        .collect();
    use tflite::BuiltinOperator as B;
    // Stride-2 layers on even sizes: PAD + VALID; the stride-1 3x3 and the 1x1 layer: one op.
    assert_eq!(
        ops,
        [
            B::PAD,
            B::CONV_2D,
            B::PAD,
            B::CONV_2D,
            B::PAD,
            B::CONV_2D,
            B::CONV_2D,
            B::CONV_2D
        ]
    );
    let tensors = g.tensors().unwrap();
    let input = tensors.get(g.inputs().unwrap().get(0) as usize);
    assert_eq!(input.type_(), tflite::TensorType::INT8);
    assert_eq!(
        input.shape().unwrap().iter().collect::<Vec<_>>(),
        [1, 64, 64, 1]
    );
    assert_eq!(
        quant(&input),
        (vec![q.input_scale], vec![q.input_zp as i64])
    );
    let output = tensors.get(g.outputs().unwrap().get(0) as usize);
    assert_eq!(
        output.shape().unwrap().iter().collect::<Vec<_>>(),
        [1, 8, 8, 32]
    );
    let convs: Vec<_> = g
        .operators()
        .unwrap()
        .iter()
        .filter(|o| codes[o.opcode_index() as usize] == B::CONV_2D)
        .collect();
    let buffers = m.buffers().unwrap();
    for (l, op) in q.layers.iter().zip(&convs) {
        let o = op.builtin_options_as_conv_2_doptions().unwrap();
        assert_eq!(o.stride_h() as usize, l.stride);
        assert_eq!(
            o.fused_activation_function() == tflite::ActivationFunctionType::RELU,
            l.relu
        );
        let w = tensors.get(op.inputs().unwrap().get(1) as usize);
        assert_eq!(w.type_(), tflite::TensorType::INT8);
        let wq = w.quantization().unwrap();
        assert_eq!(wq.quantized_dimension(), 0);
        assert_eq!(
            wq.scale().unwrap().iter().collect::<Vec<_>>(),
            l.weight_scale
        );
        let wd: Vec<i8> = buffers
            .get(w.buffer() as usize)
            .data()
            .unwrap()
            .iter()
            .map(|v| v as i8)
            .collect();
        assert_eq!(wd, l.weights);
        let b = tensors.get(op.inputs().unwrap().get(2) as usize);
        assert_eq!(b.type_(), tflite::TensorType::INT32);
        let bd: Vec<u8> = buffers
            .get(b.buffer() as usize)
            .data()
            .unwrap()
            .iter()
            .collect();
        let bd: Vec<i32> = bd
            .chunks_exact(4)
            .map(|c| i32::from_le_bytes(c.try_into().unwrap()))
            .collect();
        assert_eq!(bd, l.bias);
        let out = tensors.get(op.outputs().unwrap().get(0) as usize);
        assert_eq!(
            quant(&out),
            (vec![l.output_scale], vec![l.output_zp as i64])
        );
    }
}

#[test]
fn tflite_semantics_give_the_core_embeddings() {
    let bytes = shipped_model();
    let net = SiameseNet::from_bytes(SHIPPED_WEIGHTS).unwrap();
    let mut arena = Box::new(Arena::new());
    let mut rng = StdRng::seed_from_u64(5);
    for i in 0..12 {
        let mut x = [0i8; INPUT_LEN];
        for v in x.iter_mut() {
            *v = if i % 2 == 0 {
                rng.random_range(-128..=127)
            } else {
                rng.random_range(-40..=40)
            };
        }
        let mut e = [0i8; EMBED_LEN];
        net.embed(&x, &mut arena, &mut e).unwrap();
        assert_eq!(run_tflite(&bytes, &x), e.to_vec(), "input {i}");
    }
}

#[test]
fn f64_multipliers_are_refused() {
    let mut q = HostQModel::from_bytes(SHIPPED_WEIGHTS).unwrap();
    q.layers[1].multiplier[5] += 7;
    let e = export(&q, "t", false).unwrap_err();
    assert!(format!("{e:#}").contains("--rederive-multipliers"), "{e:#}");
    assert!(export(&q, "t", true).is_ok());
}
