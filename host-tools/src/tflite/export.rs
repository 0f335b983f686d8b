//! The quantized network of a `.ofw` file as a TensorFlow Lite model (flatbuffer bytes).
//!
//! One subgraph, NHWC, batch 1:
//!
//! - input: int8 `[1, H, W, C]` with the file's input scale and zero point;
//! - per layer: a `CONV_2D` (the per-pixel dense layer is a 1x1 convolution) with int8
//!   per-channel symmetric weights `[O, K, K, I]` (OHWI, `quantized_dimension` 0, the file's
//!   weight scales), int32 bias `[O]` (scale `s_in * s_w[c]`, zero point 0), fused `RELU` or
//!   none, and the file's output scale and zero point; where TFLite's `SAME` would read other
//!   pixels than orbfix's symmetric padding ([`super::padding`]), a `PAD` (filled with the
//!   input zero point, TFLite's int8 `PAD` default) precedes a `VALID` convolution;
//! - output: the last layer's int8 tensor `[1, h, w, D]` (NHWC, the core's embedding order).
//!
//! TFLite derives each requantization multiplier from the tensors' scales; the exporter
//! refuses a file whose stored multipliers differ from that derivation (re-derive them with
//! `orbfix quantize --rederive-multipliers`), since the model would not be bit-exact, unless
//! `allow_inexact` is set (to measure the difference).

use super::padding::{plan, PaddingPlan};
use super::schema_generated::tflite;
use crate::nn::multiplier::multiplier_mismatches;
use crate::nn::qmodel::{HostQLayer, HostQModel};
use anyhow::{bail, ensure, Result};
use flatbuffers::{FlatBufferBuilder, ForwardsUOffset, Vector, WIPOffset};

/// TFLite schema version of the written model.
pub const TFLITE_SCHEMA_VERSION: u32 = 3;

/// Operators the exporter writes, in `operator_codes` order.
const OPCODES: [tflite::BuiltinOperator; 2] = [
    tflite::BuiltinOperator::CONV_2D,
    tflite::BuiltinOperator::PAD,
];
const OP_CONV: u32 = 0;
const OP_PAD: u32 = 1;

/// What one tensor holds, before it is written.
struct TensorDesc {
    name: String,
    shape: Vec<i32>,
    ty: tflite::TensorType,
    /// Index into the buffer list (0: the empty buffer, i.e. an activation).
    buffer: u32,
    /// Per-tensor or per-channel scales and zero points; empty for none.
    scale: Vec<f32>,
    zero_point: Vec<i64>,
}

struct OpDesc {
    opcode: u32,
    inputs: Vec<i32>,
    outputs: Vec<i32>,
    /// `Some((padding, stride, relu))` for a convolution.
    conv: Option<(tflite::Padding, i32, bool)>,
}

/// The graph being assembled: tensors, constant buffers and operators.
struct Graph {
    tensors: Vec<TensorDesc>,
    buffers: Vec<Vec<u8>>,
    ops: Vec<OpDesc>,
}

impl Graph {
    fn tensor(&mut self, t: TensorDesc) -> i32 {
        self.tensors.push(t);
        (self.tensors.len() - 1) as i32
    }

    fn constant(&mut self, data: Vec<u8>) -> u32 {
        self.buffers.push(data);
        (self.buffers.len() - 1) as u32
    }

    fn activation(&mut self, name: String, shape: [usize; 3], scale: f32, zp: i32) -> i32 {
        self.tensor(TensorDesc {
            name,
            shape: [1, shape[0] as i32, shape[1] as i32, shape[2] as i32].to_vec(),
            ty: tflite::TensorType::INT8,
            buffer: 0,
            scale: vec![scale],
            zero_point: vec![zp as i64],
        })
    }
}

/// Checks what TFLite would compute differently from the file; the errors say what to do.
fn check_layer(i: usize, l: &HostQLayer) -> Result<()> {
    ensure!(
        l.kind == 1 || l.kind == 2,
        "layer {i} has kind {}, which the exporter does not know (1 convolution, 2 dense)",
        l.kind
    );
    let relu_min = if l.relu { l.output_zp } else { -128 };
    ensure!(
        l.act_min == relu_min && l.act_max == 127,
        "layer {i}: activation range [{}, {}] is not what TFLite's fused activation gives ([{relu_min}, 127])",
        l.act_min,
        l.act_max
    );
    ensure!(
        l.weight_scale.len() == l.out_c
            && l.bias.len() == l.out_c
            && l.weights.len() == l.out_c * l.kernel * l.kernel * l.in_c,
        "layer {i}: per-channel arrays do not match {} output channels",
        l.out_c
    );
    ensure!(
        l.output_scale > 0.0 && l.weight_scale.iter().all(|&s| s > 0.0),
        "layer {i}: scales must be positive for TFLite"
    );
    Ok(())
}

/// Builds the TFLite model of `model`. `description` goes into the model's description.
/// With `allow_inexact`, stored multipliers that TFLite would derive differently are
/// accepted (TFLite then computes with its own, so outputs may differ from the core's).
pub fn export(model: &HostQModel, description: &str, allow_inexact: bool) -> Result<Vec<u8>> {
    let bad = multiplier_mismatches(model);
    if let (Some(m), false) = (bad.first(), allow_inexact) {
        bail!(
            "{} stored (multiplier, shift) pairs differ from what TFLite derives from the stored scales \
             (first: layer {} channel {}: stored {:?}, TFLite {:?}), so the exported model would not be \
             bit-exact; re-derive them with `orbfix quantize --rederive-multipliers --weights IN.ofw --out OUT.ofw`",
            bad.len(),
            m.layer,
            m.channel,
            m.stored,
            m.derived
        );
    }
    let first = model.layers.first().map(|l| (l.in_h, l.in_w, l.in_c));
    let Some((h, w, c)) = first else {
        bail!("the weight file has no layers");
    };
    let mut g = Graph {
        tensors: Vec::new(),
        buffers: vec![Vec::new()],
        ops: Vec::new(),
    };
    let input = g.activation("input".into(), [h, w, c], model.input_scale, model.input_zp);
    let (mut cur, mut s_in, mut zp_in) = (input, model.input_scale, model.input_zp);
    for (i, l) in model.layers.iter().enumerate() {
        check_layer(i, l)?;
        let Some(p) = plan(l.in_h, l.in_w, l.kernel, l.stride, l.pad) else {
            bail!("layer {i}: the kernel does not fit its input");
        };
        ensure!(
            zp_in == l.input_zp,
            "layer {i}: input zero point {} does not chain with the previous output's {zp_in}",
            l.input_zp
        );
        let padding = match p {
            PaddingPlan::Same => tflite::Padding::SAME,
            PaddingPlan::Valid => tflite::Padding::VALID,
            PaddingPlan::PadThenValid { pad } => {
                let pads: Vec<u8> = [0, 0, pad, pad, pad, pad, 0, 0]
                    .iter()
                    .flat_map(|&v| (v as i32).to_le_bytes())
                    .collect();
                let buffer = g.constant(pads);
                let pads = g.tensor(TensorDesc {
                    name: format!("layer{i}/paddings"),
                    shape: vec![4, 2],
                    ty: tflite::TensorType::INT32,
                    buffer,
                    scale: vec![],
                    zero_point: vec![],
                });
                let padded = g.activation(
                    format!("layer{i}/padded"),
                    [l.in_h + 2 * pad, l.in_w + 2 * pad, l.in_c],
                    s_in,
                    zp_in,
                );
                g.ops.push(OpDesc {
                    opcode: OP_PAD,
                    inputs: vec![cur, pads],
                    outputs: vec![padded],
                    conv: None,
                });
                cur = padded;
                tflite::Padding::VALID
            }
        };
        let buffer = g.constant(l.weights.iter().map(|&v| v as u8).collect());
        let weights = g.tensor(TensorDesc {
            name: format!("layer{i}/weights"),
            shape: [l.out_c, l.kernel, l.kernel, l.in_c]
                .iter()
                .map(|&v| v as i32)
                .collect(),
            ty: tflite::TensorType::INT8,
            buffer,
            scale: l.weight_scale.clone(),
            zero_point: vec![0; l.out_c],
        });
        let buffer = g.constant(l.bias.iter().flat_map(|v| v.to_le_bytes()).collect());
        let bias = g.tensor(TensorDesc {
            name: format!("layer{i}/bias"),
            shape: vec![l.out_c as i32],
            ty: tflite::TensorType::INT32,
            buffer,
            scale: l.weight_scale.iter().map(|&sw| s_in * sw).collect(),
            zero_point: vec![0; l.out_c],
        });
        let out = g.activation(
            if i + 1 == model.layers.len() {
                "embedding".into()
            } else {
                format!("layer{i}/output")
            },
            [l.out_h(), l.out_w(), l.out_c],
            l.output_scale,
            l.output_zp,
        );
        g.ops.push(OpDesc {
            opcode: OP_CONV,
            inputs: vec![cur, weights, bias],
            outputs: vec![out],
            conv: Some((padding, l.stride as i32, l.relu)),
        });
        (cur, s_in, zp_in) = (out, l.output_scale, l.output_zp);
    }
    Ok(serialize(&g, input, cur, description))
}

fn serialize(g: &Graph, input: i32, output: i32, description: &str) -> Vec<u8> {
    let mut b = FlatBufferBuilder::with_capacity(1 << 17);
    let buffers: Vec<_> = g
        .buffers
        .iter()
        .map(|d| {
            let data = (!d.is_empty()).then(|| b.create_vector(d));
            tflite::Buffer::create(&mut b, &tflite::BufferArgs { data })
        })
        .collect();
    let buffers = b.create_vector(&buffers);
    let tensors: Vec<_> = g
        .tensors
        .iter()
        .map(|t| {
            let quantization = (!t.scale.is_empty()).then(|| {
                let scale = Some(b.create_vector(&t.scale));
                let zero_point = Some(b.create_vector(&t.zero_point));
                tflite::QuantizationParameters::create(
                    &mut b,
                    &tflite::QuantizationParametersArgs {
                        scale,
                        zero_point,
                        quantized_dimension: 0,
                        ..Default::default()
                    },
                )
            });
            let shape = Some(b.create_vector(&t.shape));
            let name = Some(b.create_string(&t.name));
            tflite::Tensor::create(
                &mut b,
                &tflite::TensorArgs {
                    shape,
                    type_: t.ty,
                    buffer: t.buffer,
                    name,
                    quantization,
                    ..Default::default()
                },
            )
        })
        .collect();
    let tensors = b.create_vector(&tensors);
    let ops: Vec<_> = g
        .ops
        .iter()
        .map(|op| {
            let (options_type, options) = match op.conv {
                Some((padding, stride, relu)) => {
                    let o = tflite::Conv2DOptions::create(
                        &mut b,
                        &tflite::Conv2DOptionsArgs {
                            padding,
                            stride_w: stride,
                            stride_h: stride,
                            fused_activation_function: if relu {
                                tflite::ActivationFunctionType::RELU
                            } else {
                                tflite::ActivationFunctionType::NONE
                            },
                            dilation_w_factor: 1,
                            dilation_h_factor: 1,
                        },
                    );
                    (tflite::BuiltinOptions::Conv2DOptions, o.as_union_value())
                }
                None => {
                    let o = tflite::PadOptions::create(&mut b, &tflite::PadOptionsArgs {});
                    (tflite::BuiltinOptions::PadOptions, o.as_union_value())
                }
            };
            let inputs = Some(b.create_vector(&op.inputs));
            let outputs = Some(b.create_vector(&op.outputs));
            tflite::Operator::create(
                &mut b,
                &tflite::OperatorArgs {
                    opcode_index: op.opcode,
                    inputs,
                    outputs,
                    builtin_options_type: options_type,
                    builtin_options: Some(options),
                    ..Default::default()
                },
            )
        })
        .collect();
    let ops = b.create_vector(&ops);
    let (inputs, outputs) = (b.create_vector(&[input]), b.create_vector(&[output]));
    let name = b.create_string("main");
    let subgraph = tflite::SubGraph::create(
        &mut b,
        &tflite::SubGraphArgs {
            tensors: Some(tensors),
            inputs: Some(inputs),
            outputs: Some(outputs),
            operators: Some(ops),
            name: Some(name),
        },
    );
    let subgraphs = b.create_vector(&[subgraph]);
    let codes: Vec<_> = OPCODES
        .iter()
        .map(|&code| {
            tflite::OperatorCode::create(
                &mut b,
                &tflite::OperatorCodeArgs {
                    deprecated_builtin_code: code.0.min(127) as i8,
                    builtin_code: code,
                    version: 1,
                    custom_code: None,
                },
            )
        })
        .collect();
    let codes: WIPOffset<Vector<ForwardsUOffset<tflite::OperatorCode>>> = b.create_vector(&codes);
    let description = b.create_string(description);
    let root = tflite::Model::create(
        &mut b,
        &tflite::ModelArgs {
            version: TFLITE_SCHEMA_VERSION,
            operator_codes: Some(codes),
            subgraphs: Some(subgraphs),
            description: Some(description),
            buffers: Some(buffers),
            ..Default::default()
        },
    );
    tflite::finish_model_buffer(&mut b, root);
    b.finished_data().to_vec()
}
