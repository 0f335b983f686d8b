//! Owned working memory of one fix on the host ([`OwnedScratch`]): the buffers the flight
//! computer keeps in static memory, as `Vec`s and boxes sized by the core's
//! [`orbfix::fix::fix_buffer_sizes`]. The one place the host allocates a fix's scratch.

use orbfix::fix::{self, FixBufferSizes, FixConfig, FixScratch};
use orbfix::map_product::{CrcCheck, MapProduct};
use orbfix::nn::model::EMBED_LEN;

/// Every buffer of one fix, exactly as long as [`fix_buffer_sizes`](fix::fix_buffer_sizes)
/// says. Borrow it as the core's [`FixScratch`] with [`OwnedScratch::scratch`].
pub struct OwnedScratch {
    /// Top-down image, bytes.
    pub top: Vec<u8>,
    /// Its validity mask, bytes.
    pub mask: Vec<u8>,
    /// Shared work area, `u32` words.
    pub work: Vec<u32>,
    /// Coarse response, Q15 cosines.
    pub response: Vec<i32>,
    /// Refinement responses.
    pub floats: Vec<f32>,
    /// The top-down image's embedding.
    pub emb: Box<[i8; EMBED_LEN]>,
    /// The relief stage's blocks.
    pub relief: Vec<i32>,
}

impl OwnedScratch {
    /// Buffers of the sizes `z`, zeroed.
    pub fn new(z: &FixBufferSizes) -> Self {
        Self {
            top: vec![0; z.top],
            mask: vec![0; z.mask],
            work: vec![0; z.work_words],
            response: vec![0; z.response],
            floats: vec![0.0; z.refine_floats],
            emb: Box::new([0; EMBED_LEN]),
            relief: vec![0; z.relief_words],
        }
    }

    /// Buffers for a fix with `cfg` over the map product `product` (its header only is read;
    /// the CRC is left to the fix).
    pub fn for_product(cfg: &FixConfig, product: &[u8]) -> anyhow::Result<Self> {
        let meta = *MapProduct::parse(product, CrcCheck::Skip)
            .map_err(|e| anyhow::anyhow!("{e}"))?
            .meta();
        let z = fix::fix_buffer_sizes(cfg, &meta).map_err(|e| anyhow::anyhow!("{e}"))?;
        Ok(Self::new(&z))
    }

    /// The core's view of these buffers.
    pub fn scratch(&mut self) -> FixScratch<'_> {
        FixScratch {
            top: &mut self.top,
            mask: &mut self.mask,
            work: &mut self.work,
            response: &mut self.response,
            refine_floats: &mut self.floats,
            nn_embedding: &mut self.emb,
            relief: &mut self.relief,
        }
    }
}
