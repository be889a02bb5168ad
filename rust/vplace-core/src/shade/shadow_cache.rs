//! The shadow-ray answers of one evaluation, kept for the next evaluation of the same G-buffer
//! in the same scene (the layout iterations of `layout::iterate`).
//!
//! A VPL of the next set at the same position (bit for bit) as one of this set gets its answers
//! from here instead of new rays. Visibility depends only on the two ends of the ray, so the
//! image is bit for bit the one [`crate::shade::evaluator::evaluate`] renders; only the number of rays
//! traced changes. Answers are two bits per (pixel, VPL) pair: traced, and not blocked.

use std::collections::HashMap;

use crate::vpl::Vpl;

/// The answers of the last evaluation (see the module docs). `Default` is an empty cache.
///
/// Invariants: `known` and `visible` hold `words` `u64` per pixel of the `width x height`
/// G-buffer (empty when `words == 0`); a `visible` bit is set only where its `known` bit is.
#[derive(Debug, Clone, Default)]
pub(crate) struct ShadowCache {
    width: usize,
    height: usize,
    /// The positions of the VPLs the bits are indexed by, bit patterns, first occurrence.
    keys: HashMap<[u32; 3], usize>,
    /// `u64` words per pixel in `known` and `visible`.
    words: usize,
    /// Per pixel, bit `j`: the pair (pixel, VPL `j`) was traced.
    known: Vec<u64>,
    /// Per pixel, bit `j`: its shadow ray was not blocked.
    visible: Vec<u64>,
    /// Pairs answered from the cache in the last evaluation instead of a ray.
    pub reused: u64,
}

/// The key of a VPL in the cache: the bit patterns of its position.
fn position_key(v: &Vpl) -> [u32; 3] {
    v.position.to_array().map(f32::to_bits)
}

/// The `u64` words one pixel's bits take for `vpls` VPLs.
#[must_use]
pub(crate) fn words_for(vpls: usize) -> usize {
    vpls.div_ceil(64)
}

/// Records the answer for VPL `j` in one pixel's `known` and `visible` words.
#[inline]
pub(crate) fn record(known: &mut [u64], visible: &mut [u64], j: usize, lit: bool) {
    known[j / 64] |= 1 << (j % 64);
    visible[j / 64] |= u64::from(lit) << (j % 64);
}

/// A cache read against a new VPL set: for each VPL, its index in the cached set.
pub(crate) struct Reuse<'a> {
    cache: &'a ShadowCache,
    previous: Vec<Option<usize>>,
}

impl Reuse<'_> {
    /// The cached answer (not blocked) for pixel `p` and VPL `j` of the new set, if traced.
    #[inline]
    pub(crate) fn lookup(&self, p: usize, j: usize) -> Option<bool> {
        self.previous[j].and_then(|k| self.cache.lookup(p, k))
    }
}

impl ShadowCache {
    /// The cache as seen by an evaluation of `vpls` over a `width x height` G-buffer; `None`
    /// when it holds nothing for that size.
    pub(crate) fn reuse(&self, vpls: &[Vpl], width: usize, height: usize) -> Option<Reuse<'_>> {
        (self.width == width && self.height == height && self.words > 0).then(|| Reuse {
            cache: self,
            previous: vpls
                .iter()
                .map(|v| self.keys.get(&position_key(v)).copied())
                .collect(),
        })
    }

    /// The cache of an evaluation of `vpls` over a `width x height` G-buffer: `known` and
    /// `visible` hold [`words_for`]`(vpls.len())` words per pixel; `reused` pairs were
    /// answered from the previous cache.
    pub(crate) fn new(
        vpls: &[Vpl],
        width: usize,
        height: usize,
        known: Vec<u64>,
        visible: Vec<u64>,
        reused: u64,
    ) -> Self {
        let mut keys = HashMap::with_capacity(vpls.len());
        for (j, v) in vpls.iter().enumerate() {
            keys.entry(position_key(v)).or_insert(j);
        }
        Self {
            width,
            height,
            keys,
            words: words_for(vpls.len()),
            known,
            visible,
            reused,
        }
    }

    /// The cached answer for pixel `p` and VPL `k` of the cached set, if it was traced.
    #[inline]
    fn lookup(&self, p: usize, k: usize) -> Option<bool> {
        let (word, bit) = (self.words * p + k / 64, k % 64);
        (self.known[word] >> bit & 1 == 1).then(|| self.visible[word] >> bit & 1 == 1)
    }
}
