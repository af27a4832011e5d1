//! Sign bits: one bit per sample (`f < 0`), 64 samples to a word, so that the cubes the
//! surface passes through (corners of both signs) are found 64 at a time by a few word
//! operations, and only those are visited. The sign pass reads every sample of the volume,
//! so it uses SIMD compares (SSE2 always on x86-64, AVX2 where the CPU has it); the
//! extraction's `unsafe` for speed is here, each block with the reason it is sound (but for
//! one unchecked read of a cube's corners in `extract_slab`, with its own).

use rayon::prelude::*;
use skelform_field::grid::Volume;

/// The bits of word `w` of a row that stand for the items `0..count` of the row (samples,
/// or cubes and x-edges, which are one fewer).
#[inline]
pub(super) fn word_mask(w: usize, count: usize) -> u64 {
    let n = count.saturating_sub(w * 64).min(64);
    if n == 64 { u64::MAX } else { (1u64 << n) - 1 }
}

/// Bit `i` of the row words: whether sample `i` of the row is inside (`v < threshold`:
/// `f < 0` for samples relative to the level), with `signs64` for each whole word.
#[inline(always)]
fn row_signs(values: &[f32], out: &mut [u64], threshold: f32, signs64: impl Fn(&[f32]) -> u64) {
    for (w, chunk) in out.iter_mut().zip(values.chunks(64)) {
        *w = if chunk.len() == 64 { signs64(chunk) } else { signs_scalar(chunk, threshold) };
    }
}

pub(super) fn signs_scalar(chunk: &[f32], threshold: f32) -> u64 {
    let mut bits = 0u64;
    for (b, &v) in chunk.iter().enumerate() {
        bits |= ((v < threshold) as u64) << b;
    }
    bits
}

/// [`signs_scalar`] of 64 samples, four at a time with SSE2 (part of every x86-64 CPU):
/// sixteen compares and mask extractions instead of 64 compares, shifts and ors.
/// `v < threshold` exactly as the scalar form (false for NaN, and for −0 when it is 0).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn signs64(chunk: &[f32], threshold: f32) -> u64 {
    use std::arch::x86_64::{_mm_cmplt_ps, _mm_loadu_ps, _mm_movemask_ps, _mm_set1_ps};
    assert_eq!(chunk.len(), 64);
    // SAFETY: SSE is in the x86-64 baseline; a broadcast reads no memory.
    let t = unsafe { _mm_set1_ps(threshold) };
    let mut bits = 0u64;
    for q in 0..16 {
        // SAFETY: SSE2 is in the x86-64 baseline, and `4 * q + 3 < 64 == chunk.len()`
        // (asserted above), so the unaligned load reads inside the slice.
        let m = unsafe {
            let v = _mm_loadu_ps(chunk.as_ptr().add(4 * q));
            _mm_movemask_ps(_mm_cmplt_ps(v, t))
        };
        bits |= (m as u64) << (4 * q);
    }
    bits
}

#[cfg(not(target_arch = "x86_64"))]
fn signs64(chunk: &[f32], threshold: f32) -> u64 {
    signs_scalar(chunk, threshold)
}

/// Sign words with AVX2 where the CPU has it: eight samples per compare. The sign pass
/// reads every sample of the volume, so its instruction count matters as much as memory.
#[cfg(target_arch = "x86_64")]
mod wide {
    pub(super) fn available() -> bool {
        std::arch::is_x86_feature_detected!("avx2")
    }

    /// [`super::signs64`] eight samples at a time (`_CMP_LT_OQ`: false for NaN, as
    /// `v < threshold`), the compares' lanes packed to bytes, 32 samples to a mask
    /// extraction: fewer than half the instructions of a mask extraction, shift and or for
    /// each compare.
    ///
    /// # Safety
    /// The CPU must support AVX2 ([`available`]).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn signs64(chunk: &[f32], threshold: f32) -> u64 {
        use std::arch::x86_64::{
            _CMP_LT_OQ, _mm256_castps_si256, _mm256_cmp_ps, _mm256_loadu_ps, _mm256_movemask_epi8,
            _mm256_packs_epi16, _mm256_packs_epi32, _mm256_permutevar8x32_epi32, _mm256_set1_ps,
            _mm256_setr_epi32, _mm256_setzero_si256,
        };
        assert_eq!(chunk.len(), 64);
        let t = _mm256_set1_ps(threshold);
        // Each 128-bit lane of two packs holds, per compare of four, four bytes: lane 0 the
        // low halves of the four compares and lane 1 their high halves; this puts each
        // compare's eight bytes together, in sample order.
        let order = _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7);
        let mut c = [_mm256_setzero_si256(); 8];
        for (q, c) in c.iter_mut().enumerate() {
            // All ones (−1) where the sample is inside, else 0: packing with signed
            // saturation keeps −1 and 0, so each byte's top bit is its sample's flag.
            // SAFETY: AVX2 is there (the caller's promise), and `8 * q + 7 < 64 ==
            // chunk.len()` (asserted above), so the unaligned load reads inside the slice.
            *c = unsafe {
                let v = _mm256_loadu_ps(chunk.as_ptr().add(8 * q));
                _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LT_OQ>(v, t))
            };
        }
        let mut bits = 0u64;
        for h in 0..2 {
            let c = &c[4 * h..4 * h + 4];
            let lo = _mm256_packs_epi32(c[0], c[1]);
            let hi = _mm256_packs_epi32(c[2], c[3]);
            let bytes = _mm256_permutevar8x32_epi32(_mm256_packs_epi16(lo, hi), order);
            bits |= u64::from(_mm256_movemask_epi8(bytes) as u32) << (32 * h);
        }
        bits
    }

    /// # Safety
    /// The CPU must support AVX2 ([`available`]).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn layer_signs(
        layer: &[f32],
        nx: usize,
        words: usize,
        out: &mut [u64],
        threshold: f32,
        ahead: Option<super::Ahead<'_>>,
    ) {
        // The loop spelled out here rather than through `row_signs` with a closure: a
        // closure is compiled without AVX2, and `signs64` is then a call per word with
        // its constants set up each time.
        let whole = nx / 64;
        for (j, (row, o)) in layer.chunks(nx).zip(out.chunks_mut(words)).enumerate() {
            if let Some(a) = &ahead {
                a.row(j, nx);
            }
            for (w, o) in o[..whole].iter_mut().enumerate() {
                // SAFETY: AVX2 is there: the caller's promise.
                *o = unsafe { signs64(&row[64 * w..64 * w + 64], threshold) };
            }
            if whole < words {
                o[whole] = super::signs_scalar(&row[64 * whole..], threshold);
            }
        }
    }
}

/// A layer further on whose rows [`layer_signs`] fetches into the cache as it goes: those
/// whose row of cubes in the layer of cubes under the layer signed is likely to be passed
/// over, that is, whose sample row and the next are alike and uniform in the layer below
/// (`passed`, its [`row_classes`]). The loop over cubes fetches the others.
#[derive(Clone, Copy)]
pub(super) struct Ahead<'a> {
    pub(super) values: &'a [f32],
    pub(super) passed: &'a [u8],
}

impl Ahead<'_> {
    /// Fetches sample row `j` (of `nx` samples) if its row of cubes is likely passed over.
    #[inline(always)]
    fn row(&self, j: usize, nx: usize) {
        let c = &self.passed;
        if same_uniform(c[j], c[(j + 1).min(c.len() - 1)]) {
            prefetch(&self.values[j * nx..(j + 1) * nx]);
        }
    }
}

/// Sign words of every row of a layer (`ny` rows of `words` words): bit set where the raw
/// value is below `threshold` (see [`skelform_field::grid::Level`]); rows of `ahead`
/// fetched on the way.
pub(super) fn layer_signs(
    layer: &[f32],
    nx: usize,
    words: usize,
    out: &mut [u64],
    threshold: f32,
    ahead: Option<Ahead<'_>>,
) {
    #[cfg(target_arch = "x86_64")]
    if wide::available() {
        // SAFETY: AVX2 was detected at run time.
        unsafe { wide::layer_signs(layer, nx, words, out, threshold, ahead) };
        return;
    }
    for (j, (row, o)) in layer.chunks(nx).zip(out.chunks_mut(words)).enumerate() {
        if let Some(a) = &ahead {
            a.row(j, nx);
        }
        row_signs(row, o, threshold, |c| signs64(c, threshold));
    }
}

/// A sample row whose samples are all outside (`f >= 0`): its sign words are all zero.
pub(super) const ROW_OUT: u8 = 0;
/// A sample row whose samples are all inside.
pub(super) const ROW_IN: u8 = 1;
/// A sample row with samples of both signs.
pub(super) const ROW_MIXED: u8 = 2;

/// The class of every sample row of a layer ([`ROW_OUT`], [`ROW_IN`] or [`ROW_MIXED`]),
/// from its sign words: a few word operations a row, after which rows far from the surface
/// (most of them around a compact shape) are passed over by the cube loop and the edge
/// numberings with one comparison, as Flying Edges trims its rows.
#[inline(always)]
pub(super) fn row_classes(signs: &[u64], nx: usize, words: usize, classes: &mut Vec<u8>) {
    let ny = signs.len() / words;
    classes.resize(ny, ROW_MIXED);
    // The bits past the row's last sample are zero (`row_signs`): set them for the "all
    // inside" test.
    let past = !word_mask(words - 1, nx);
    for (row, class) in signs.chunks_exact(words).zip(classes.iter_mut()) {
        let (mut or, mut and) = (0u64, u64::MAX);
        for &w in &row[..words - 1] {
            or |= w;
            and &= w;
        }
        let last = row[words - 1];
        or |= last;
        and &= last | past;
        *class = if or == 0 {
            ROW_OUT
        } else if and == u64::MAX {
            ROW_IN
        } else {
            ROW_MIXED
        };
    }
}

/// Whether rows `a` and `b` (classes from [`row_classes`]) are both all outside or both all
/// inside: no edge between them, or along either, is crossed.
#[inline(always)]
pub(super) fn same_uniform(a: u8, b: u8) -> bool {
    a == b && a != ROW_MIXED
}

/// Asks the CPU to bring `values` into its cache ahead of use: a hint, with no effect on
/// the values or on correctness.
#[inline]
pub(super) fn prefetch(values: &[f32]) {
    #[cfg(target_arch = "x86_64")]
    for line in values.chunks(16) {
        use std::arch::x86_64::{_MM_HINT_T1, _mm_prefetch};
        // SAFETY: a prefetch never faults or changes memory, whatever the address; SSE is in
        // the x86-64 baseline.
        unsafe { _mm_prefetch::<_MM_HINT_T1>(line.as_ptr().cast()) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = values;
}

/// The sign words of the four sample rows around row `j` of cubes: rows `j` and `j + 1` of
/// the layer below, then of the layer above (corner bit order: y, then z).
#[inline]
fn cube_rows<'a>(below: &'a [u64], above: &'a [u64], j: usize, words: usize) -> [&'a [u64]; 4] {
    let row = |layer: &'a [u64], j: usize| &layer[j * words..(j + 1) * words];
    [row(below, j), row(below, j + 1), row(above, j), row(above, j + 1)]
}

/// Bit `b` of the result: whether cube `64·w + b` of a row of cubes has corners of both
/// signs, from the sign words of the four sample rows around it (bits past the row's last
/// cube are garbage: mask them).
#[inline]
fn mixed_cubes(rows: &[&[u64]; 4], w: usize) -> u64 {
    let any = |w: usize| rows.iter().fold(0u64, |m, r| m | r[w]);
    let all = |w: usize| rows.iter().fold(u64::MAX, |m, r| m & r[w]);
    let (or, and) = (any(w), all(w));
    let words = rows[0].len();
    let (or_next, and_next) = if w + 1 < words { (any(w + 1) & 1, all(w + 1) & 1) } else { (0, 0) };
    // Cube i spans samples i and i + 1.
    let some_inside = or | (or >> 1) | (or_next << 63);
    let all_inside = and & ((and >> 1) | (and_next << 63));
    some_inside & !all_inside
}

/// How many cubes of the volume the surface passes through (corners of both signs): the
/// classification phase of extraction on its own, for statistics and benchmarks.
pub fn surface_cubes(volume: &Volume) -> u64 {
    let [nx, ny, nz] = volume.grid.dims;
    let layer = nx * ny;
    let words = nx.div_ceil(64);
    (0..nz - 1)
        .into_par_iter()
        .map(|k| {
            let (mut below, mut above) = (vec![0u64; ny * words], vec![0u64; ny * words]);
            let at = |k: usize| &volume.values[k * layer..(k + 1) * layer];
            layer_signs(at(k), nx, words, &mut below, 0.0, None);
            layer_signs(at(k + 1), nx, words, &mut above, 0.0, None);
            let mut count = 0u64;
            for j in 0..ny - 1 {
                let rows = cube_rows(&below, &above, j, words);
                for w in 0..words {
                    count += (mixed_cubes(&rows, w) & word_mask(w, nx - 1)).count_ones() as u64;
                }
            }
            count
        })
        .sum()
}

/// Calls `f(i, j, case)` for every cube of a layer of cubes whose corners have both signs,
/// in row order, given the sign words of the sample layers below and above it and their
/// rows' classes ([`row_classes`]); `row(j)` before the cubes of row `j`. A row of cubes
/// whose four sample rows are all outside, or all inside, has no such cube and is passed
/// over without looking at its words (nor a call of `row`).
#[inline(always)]
pub(super) fn for_each_mixed_cube(
    (below, below_classes): (&[u64], &[u8]),
    (above, above_classes): (&[u64], &[u8]),
    nx: usize,
    ny: usize,
    mut row: impl FnMut(usize),
    mut f: impl FnMut(usize, usize, usize),
) {
    let words = nx.div_ceil(64);
    let (bc, ac) = (&below_classes[..ny], &above_classes[..ny]);
    for j in 0..ny - 1 {
        let c = bc[j];
        if same_uniform(c, bc[j + 1]) && same_uniform(c, ac[j]) && same_uniform(c, ac[j + 1]) {
            continue;
        }
        row(j);
        let rows = cube_rows(below, above, j, words);
        for w in 0..words {
            // Cubes are i < nx - 1: the last sample's bit and those past it are masked out.
            let mut mixed = mixed_cubes(&rows, w) & word_mask(w, nx - 1);
            while mixed != 0 {
                let i = w * 64 + mixed.trailing_zeros() as usize;
                mixed &= mixed - 1;
                let case = two_bits(rows[0], i)
                    | two_bits(rows[1], i) << 2
                    | two_bits(rows[2], i) << 4
                    | two_bits(rows[3], i) << 6;
                f(i, j, case);
            }
        }
    }
}

/// Bits `i` and `i + 1` of a row of sign words: the inside flags of a cube's two corners
/// on that row.
#[inline]
fn two_bits(row: &[u64], i: usize) -> usize {
    let (w, b) = (i / 64, i % 64);
    let lo = row[w] >> b;
    let bits = if b == 63 { (lo & 1) | ((row[w + 1] & 1) << 1) } else { lo & 3 };
    bits as usize
}
