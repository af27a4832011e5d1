//! Vertex numbering, as in Flying Edges: the crossed edges of a sample layer, and those
//! between two layers, are numbered in a fixed order computed from the layers' sign bits
//! alone, so a cube finds the vertex on its edge by a population count (no map to look it up
//! in), and two slabs that share a layer agree on its numbers without looking at each
//! other's work.

use skelform_field::grid::{Grid, Level};

use super::signs::{ROW_MIXED, same_uniform, word_mask};
use super::slabs::SlabStore;
use super::{GridVertex, Near, Place, SlabVertex};
use crate::grid::cell::crossing;

/// One word of a row of edges: the crossed ones (bit `i`: the edge from sample `64·w + i`)
/// and how many crossed edges come before the word in their numbering.
#[derive(Clone, Copy, Default)]
pub(super) struct Counted {
    pub(super) bits: u64,
    pub(super) before: u32,
}

impl Counted {
    /// The number of crossed edge `i % 64` of the word.
    #[inline]
    pub(super) fn number(&self, i: usize) -> u32 {
        debug_assert!(self.bits >> (i % 64) & 1 == 1, "edge {i} is not crossed");
        self.before + (self.bits & ((1u64 << (i % 64)) - 1)).count_ones()
    }
}

/// The crossed x- and y-edges of one sample layer (corners of both signs), numbered row by
/// row: in each row its x-edges, then the y-edges to the next row, each by x. The numbers
/// come from the layer's sign words alone, so the two slabs that share a layer agree on them
/// without looking at each other's work, as Flying Edges numbers its edges by counting.
#[derive(Default)]
pub(super) struct LayerNumbering {
    pub(super) words: usize,
    /// Per row and word, the crossed x- and y-edges.
    /// Words of rows with no crossed edge (not in `live`) are left as an earlier layer
    /// had them: nothing reads them, since a cube asks only for its crossed edges' numbers.
    pub(super) x: Vec<Counted>,
    pub(super) y: Vec<Counted>,
    /// The rows with crossed x-edges, or y-edges to the next row, in order.
    live: Vec<u32>,
    pub(super) total: u32,
    /// The number of the layer's first vertex in its slab's output, or [`BORROWED`] when
    /// the layer's vertices are the next slab's.
    pub(super) offset: u32,
}

impl LayerNumbering {
    /// Numbers the edges of a layer of `ny` rows of sign words (see [`layer_signs`]), whose
    /// rows' classes are `classes` ([`row_classes`](super::signs::row_classes)): a row all inside or all outside, like
    /// the next row, has no crossed edge and is passed over.
    #[inline(always)]
    pub(super) fn build(
        &mut self,
        signs: &[u64],
        classes: &[u8],
        nx: usize,
        ny: usize,
        words: usize,
    ) {
        self.words = words;
        self.x.resize(ny * words, Counted::default());
        self.y.resize(ny * words, Counted::default());
        self.live.clear();
        let (x_last, y_last) = (word_mask(words - 1, nx - 1), word_mask(words - 1, nx));
        let mut count = 0u32;
        for j in 0..ny {
            let c = classes[j];
            if c != ROW_MIXED && (j + 1 == ny || same_uniform(c, classes[j + 1])) {
                continue;
            }
            self.live.push(j as u32);
            let row = &signs[j * words..][..words];
            let xs = &mut self.x[j * words..][..words];
            for w in 0..words {
                let (bits, mask) = match row.get(w + 1) {
                    Some(next) => (row[w] ^ ((row[w] >> 1) | (next << 63)), u64::MAX),
                    None => (row[w] ^ (row[w] >> 1), x_last),
                };
                let bits = bits & mask;
                xs[w] = Counted { bits, before: count };
                count += bits.count_ones();
            }
            if j + 1 < ny {
                let up = &signs[(j + 1) * words..][..words];
                count_across(row, up, y_last, &mut self.y[j * words..][..words], &mut count);
            }
        }
        self.total = count;
    }

    compiled_twice! {
        /// Makes the layer's vertices in the order of their numbers, from the layer's raw
        /// values (`nx·ny`, x fastest) read through `near`'s level; `k` is the layer's index.
        pub(super) fn emit<V: SlabVertex, L: Level>(
            &self,
            grid: &Grid,
            vals: &[f32],
            near: &Near<'_, L>,
            k: usize,
            store: &mut SlabStore<'_, V>,
        ) => emit_v3, emit_in
    }

    /// The work of [`Self::emit`], in each of its compiled copies (the closures it hands
    /// on are always inlined for that reason: one left as a call would run baseline code).
    #[inline(always)]
    fn emit_in<V: SlabVertex, L: Level>(
        &self,
        grid: &Grid,
        vals: &[f32],
        near: &Near<'_, L>,
        k: usize,
        store: &mut SlabStore<'_, V>,
    ) {
        let [nx, ny, _] = grid.dims;
        // Two closures, one per axis, so that each loop makes its records with the axis a
        // constant (one closure taking the axis is left as a call, the axis unknown in it).
        self.for_each_edge(
            ny,
            store,
            #[inline(always)]
            |store, i, j| {
                let at = i + nx * j;
                let ends = [near.level.sample(vals[at]), near.level.sample(vals[at + 1])];
                store.push_vertex(edge_record(grid, [i, j, k], 0, ends, near));
            },
            #[inline(always)]
            |store, i, j| {
                let at = i + nx * j;
                let ends = [near.level.sample(vals[at]), near.level.sample(vals[at + nx])];
                store.push_vertex(edge_record(grid, [i, j, k], 1, ends, near));
            },
        );
    }

    /// Calls `x(state, i, j)` or `y(state, i, j)` for each crossed x- or y-edge of the layer
    /// (of `ny` rows) from sample `(i, j)`, in the order of their numbers.
    #[inline(always)]
    pub(super) fn for_each_edge<S>(
        &self,
        ny: usize,
        state: &mut S,
        mut x: impl FnMut(&mut S, usize, usize),
        mut y: impl FnMut(&mut S, usize, usize),
    ) {
        for &j in &self.live {
            let j = j as usize;
            let row = j * self.words..(j + 1) * self.words;
            for_each_bit(
                &self.x[row.clone()],
                #[inline(always)]
                |i| x(state, i, j),
            );
            if j + 1 < ny {
                for_each_bit(
                    &self.y[row],
                    #[inline(always)]
                    |i| y(state, i, j),
                );
            }
        }
    }

    /// The number of the crossed x (`axis` 0) or y edge from sample `(i, j)`. (Cubes find
    /// their edges' numbers through `SlabSink`, which indexes the rows itself.)
    #[cfg(test)]
    pub(super) fn number(&self, axis: usize, i: usize, j: usize) -> u32 {
        let words = if axis == 0 { &self.x } else { &self.y };
        words[j * self.words + i / 64].number(i)
    }
}

/// The crossed z-edges between two sample layers, numbered row by row like
/// [`LayerNumbering`]'s edges.
#[derive(Default)]
pub(super) struct ZNumbering {
    pub(super) words: usize,
    /// As in [`LayerNumbering`], the words of rows not in `live` are stale and unread.
    pub(super) edges: Vec<Counted>,
    /// The rows with crossed z-edges, in order.
    live: Vec<u32>,
    /// The output number of the first of them.
    pub(super) offset: u32,
}

impl ZNumbering {
    /// Numbers the z-edges between two layers of sign words, given their rows' classes
    /// ([`row_classes`](super::signs::row_classes)): a row all inside, or all outside, in both layers is passed over.
    #[inline(always)]
    pub(super) fn build(
        &mut self,
        (lower, lower_classes): (&[u64], &[u8]),
        (upper, upper_classes): (&[u64], &[u8]),
        nx: usize,
        words: usize,
    ) {
        self.words = words;
        self.edges.resize(lower.len(), Counted::default());
        self.live.clear();
        let last = word_mask(words - 1, nx);
        let mut count = 0u32;
        let rows = lower.chunks_exact(words).zip(upper.chunks_exact(words));
        let classes = lower_classes.iter().zip(upper_classes);
        for (j, (((a, b), out), (&ca, &cb))) in
            rows.zip(self.edges.chunks_exact_mut(words)).zip(classes).enumerate()
        {
            if same_uniform(ca, cb) {
                continue;
            }
            self.live.push(j as u32);
            count_across(a, b, last, out, &mut count);
        }
    }

    compiled_twice! {
        /// Makes the vertices in the order of their numbers; `lower` and `upper` are the
        /// two layers' raw values, read through `near`'s level, `k` the lower one's index.
        pub(super) fn emit<V: SlabVertex, L: Level>(
            &self,
            grid: &Grid,
            lower: &[f32],
            upper: &[f32],
            near: &Near<'_, L>,
            k: usize,
            store: &mut SlabStore<'_, V>,
        ) => emit_v3, emit_in
    }

    /// The work of [`Self::emit`], in each of its compiled copies (the closures it hands
    /// on are always inlined for that reason: one left as a call would run baseline code).
    #[inline(always)]
    fn emit_in<V: SlabVertex, L: Level>(
        &self,
        grid: &Grid,
        lower: &[f32],
        upper: &[f32],
        near: &Near<'_, L>,
        k: usize,
        store: &mut SlabStore<'_, V>,
    ) {
        let nx = grid.dims[0];
        self.for_each_edge(
            #[inline(always)]
            |i, j| {
                let at = i + nx * j;
                let ends = [near.level.sample(lower[at]), near.level.sample(upper[at])];
                store.push_vertex(edge_record(grid, [i, j, k], 2, ends, near));
            },
        );
    }

    /// Calls `f(i, j)` for each crossed z-edge from sample `(i, j)`, in the order of their
    /// numbers.
    #[inline(always)]
    pub(super) fn for_each_edge(&self, mut f: impl FnMut(usize, usize)) {
        for &j in &self.live {
            let j = j as usize;
            for_each_bit(
                &self.edges[j * self.words..][..self.words],
                #[inline(always)]
                |i| f(i, j),
            );
        }
    }

    /// The number of the crossed z-edge from sample `(i, j)`.
    #[cfg(test)]
    pub(super) fn number(&self, i: usize, j: usize) -> u32 {
        self.edges[j * self.words + i / 64].number(i)
    }
}

/// Numbers the crossed edges from each sample of row `a` to the same sample of row `b` (the
/// next row, or the row above in the next layer) into `out`, continuing from `count`; `last`
/// masks the samples past the row's end in its last word.
#[inline]
fn count_across(a: &[u64], b: &[u64], last: u64, out: &mut [Counted], count: &mut u32) {
    let words = out.len();
    for (w, o) in out.iter_mut().enumerate() {
        let mask = if w + 1 < words { u64::MAX } else { last };
        let bits = (a[w] ^ b[w]) & mask;
        *o = Counted { bits, before: *count };
        *count += bits.count_ones();
    }
}

/// Calls `f(i)` for each crossed edge `i` of a row, in order.
#[inline(always)]
fn for_each_bit(words: &[Counted], mut f: impl FnMut(usize)) {
    for (w, word) in words.iter().enumerate() {
        let mut bits = word.bits;
        while bits != 0 {
            f(w * 64 + bits.trailing_zeros() as usize);
            bits &= bits - 1;
        }
    }
}

/// The record of the vertex where the surface crosses the lattice edge from sample `base`
/// along `axis`, whose end samples are `ends`. (Always inlined into the loops over a row's
/// crossed edges: a record that reads the samples around its vertex is most of the cost of
/// a vertex, and as a call it is returned through memory and overlaps less with the next.)
#[inline(always)]
fn edge_record<V: SlabVertex, L: Level>(
    grid: &Grid,
    base: [usize; 3],
    axis: usize,
    ends: [f32; 2],
    near: &Near<'_, L>,
) -> V {
    let v = GridVertex {
        base: [base[0] as u32, base[1] as u32, base[2] as u32],
        place: Place::Edge { dir: 1 << axis, t: crossing(ends[0], ends[1]) },
    };
    V::make(grid, v, ends, near)
}
