//! Host side of the siamese CNN matcher: the float model (candle), on-the-fly training
//! pairs, contrastive training, post-training int8 quantization, the `.ofw` writer/reader,
//! a bit-exact quantized reference and the 441-window evaluation.

pub mod data;
pub mod eval;
pub mod float_matcher;
pub mod float_model;
pub mod multiplier;
pub mod qmodel;
pub mod quantize;
pub mod realdata;
pub mod reference;
pub mod train;
pub mod weights_file;
