//! Sparse storage for what propagation knows about the lattice: corner values and which
//! cubes were visited, in dense 8×8×8 bricks found through a hash map of bricks.
//!
//! Storage grows with the number of bricks the surface passes through, i.e. with its area;
//! looking up a value is one hash lookup per brick (cached for the last brick touched) and an
//! array index, instead of one hash lookup per corner.

use rustc_hash::FxHashMap;

use crate::lattice::memory::{map_bytes, vec_bytes};

const SHIFT: u32 = 3;
const SIDE: u32 = 1 << SHIFT;
const MASK: u32 = SIDE - 1;
const CELLS: usize = (SIDE * SIDE * SIDE) as usize;

/// A corner not evaluated yet.
const UNKNOWN: f32 = f32::NAN;
/// A corner queued for evaluation (finite values are clamped to ±f32::MAX, so never this).
pub const PENDING: f32 = f32::INFINITY;

struct Brick {
    values: [f32; CELLS],
    /// 0: not visited; otherwise 1 + the index of the seed whose component reached the cube
    /// whose lowest corner is this point.
    owner: [u32; CELLS],
    /// Vertex on the segment from each point in each direction (`u32::MAX`: none yet),
    /// allocated when the brick first holds a vertex.
    edges: Vec<u32>,
    /// Field gradient at each point (empty unless the run keeps gradients), allocated when
    /// the brick first gets a gradient.
    grads: Vec<[f32; 3]>,
    /// The brick's key in `index`.
    key: u64,
    /// With tracking: the points evaluated since [`Lattice::take_fresh`], and those of them
    /// whose value was not finite, a bit each.
    fresh: Fresh,
}

/// The points of one brick evaluated in a stretch of a run (see [`Lattice::take_fresh`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Fresh {
    /// The brick's key.
    pub key: u64,
    /// A bit per point of the brick (by slot).
    pub points: [u64; CELLS / 64],
    /// The points among them whose value was NaN or infinite.
    pub bad: [u64; CELLS / 64],
}

pub struct Lattice {
    bricks: Vec<Brick>,
    /// Directions a vertex segment can take from a point: 3 for cubes (axes), 7 when
    /// tetrahedra also use face and body diagonals.
    directions: usize,
    index: FxHashMap<u64, u32>,
    /// Bricks per axis.
    dims: [u64; 3],
    last: Option<(u64, u32)>,
    visited: u64,
    /// Bricks whose `edges` are allocated.
    edge_bricks: u64,
    /// Bricks whose `grads` are allocated.
    grad_bricks: u64,
    /// Whether evaluated points are noted ([`Lattice::note`]).
    track: bool,
    /// Bricks with points noted since [`Lattice::take_fresh`].
    dirty: Vec<u32>,
}

#[inline]
fn slot(p: [u32; 3]) -> usize {
    ((p[0] & MASK) | ((p[1] & MASK) << SHIFT) | ((p[2] & MASK) << (2 * SHIFT))) as usize
}

impl Lattice {
    /// Storage for a lattice of `points` points per axis, whose segments go in up to
    /// `directions` directions (3 or 7).
    pub fn new(points: [usize; 3], directions: usize) -> Self {
        Lattice {
            bricks: Vec::new(),
            directions,
            index: FxHashMap::default(),
            dims: points.map(|n| (n as u64).div_ceil(SIDE as u64)),
            last: None,
            visited: 0,
            edge_bricks: 0,
            grad_bricks: 0,
            track: false,
            dirty: Vec::new(),
        }
    }

    /// Notes the points evaluated from now on ([`Lattice::note`]).
    pub fn track(&mut self) {
        self.track = true;
    }

    /// Whether evaluated points are noted.
    pub fn tracking(&self) -> bool {
        self.track
    }

    /// Notes that the point `p` was evaluated, and whether its value was not finite.
    #[inline]
    pub fn note(&mut self, p: [u32; 3], bad: bool) {
        let i = self.find_or_add(p);
        let s = slot(p);
        let fresh = &mut self.bricks[i as usize].fresh;
        if fresh.points == [0; CELLS / 64] {
            self.dirty.push(i);
        }
        fresh.points[s / 64] |= 1 << (s % 64);
        fresh.bad[s / 64] |= u64::from(bad) << (s % 64);
    }

    /// The points noted since the last call, by brick (in the order the bricks were first
    /// noted); forgets them.
    pub fn take_fresh(&mut self) -> Vec<Fresh> {
        let dirty = std::mem::take(&mut self.dirty);
        dirty
            .into_iter()
            .map(|i| {
                let b = &mut self.bricks[i as usize];
                let mut f = std::mem::take(&mut b.fresh);
                f.key = b.key;
                f
            })
            .collect()
    }

    #[inline]
    fn brick_key(&self, p: [u32; 3]) -> u64 {
        let b = p.map(|x| (x >> SHIFT) as u64);
        b[0] + self.dims[0] * (b[1] + self.dims[1] * b[2])
    }

    #[inline]
    fn find(&mut self, p: [u32; 3]) -> Option<u32> {
        let key = self.brick_key(p);
        if let Some((k, i)) = self.last
            && k == key
        {
            return Some(i);
        }
        let i = *self.index.get(&key)?;
        self.last = Some((key, i));
        Some(i)
    }

    #[inline]
    fn find_or_add(&mut self, p: [u32; 3]) -> u32 {
        if let Some(i) = self.find(p) {
            return i;
        }
        let key = self.brick_key(p);
        let i = self.bricks.len() as u32;
        self.bricks.push(Brick {
            values: [UNKNOWN; CELLS],
            owner: [0; CELLS],
            edges: Vec::new(),
            grads: Vec::new(),
            key,
            fresh: Fresh::default(),
        });
        self.index.insert(key, i);
        self.last = Some((key, i));
        i
    }

    /// The value at a lattice point: NaN if not evaluated, [`PENDING`] if queued.
    #[inline]
    pub fn value(&mut self, p: [u32; 3]) -> f32 {
        match self.find(p) {
            Some(i) => self.bricks[i as usize].values[slot(p)],
            None => UNKNOWN,
        }
    }

    #[inline]
    pub fn set_value(&mut self, p: [u32; 3], v: f32) {
        let i = self.find_or_add(p);
        self.bricks[i as usize].values[slot(p)] = v;
    }

    /// Sets the value and the gradient at a lattice point.
    #[inline]
    pub fn set_value_grad(&mut self, p: [u32; 3], v: f32, g: [f32; 3]) {
        let i = self.find_or_add(p) as usize;
        let brick = &mut self.bricks[i];
        if brick.grads.is_empty() {
            brick.grads = vec![[f32::NAN; 3]; CELLS];
            self.grad_bricks += 1;
        }
        brick.values[slot(p)] = v;
        brick.grads[slot(p)] = g;
    }

    /// The gradient at a lattice point set by [`Lattice::set_value_grad`] (NaN if none).
    #[inline]
    pub fn grad(&mut self, p: [u32; 3]) -> [f32; 3] {
        match self.find(p) {
            Some(i) => self.bricks[i as usize].grads.get(slot(p)).copied().unwrap_or([f32::NAN; 3]),
            None => [f32::NAN; 3],
        }
    }

    /// Marks a point for evaluation; true if it was not known nor queued before.
    #[inline]
    pub fn queue(&mut self, p: [u32; 3]) -> bool {
        let i = self.find_or_add(p) as usize;
        let v = &mut self.bricks[i].values[slot(p)];
        if v.is_nan() {
            *v = PENDING;
            true
        } else {
            false
        }
    }

    /// The seed whose component visited the cube at `p`, if any.
    #[inline]
    pub fn owner(&mut self, p: [u32; 3]) -> Option<usize> {
        let i = self.find(p)?;
        match self.bricks[i as usize].owner[slot(p)] {
            0 => None,
            o => Some(o as usize - 1),
        }
    }

    /// Marks the cube at `p` visited by `seed`'s component.
    #[inline]
    pub fn visit(&mut self, p: [u32; 3], seed: usize) {
        let i = self.find_or_add(p) as usize;
        let o = &mut self.bricks[i].owner[slot(p)];
        if *o == 0 {
            self.visited += 1;
        }
        *o = seed as u32 + 1;
    }

    /// The vertex on the segment from `p` in direction `dir` (a bit mask; 1, 2, 4 for the
    /// axes), making it with `make` the first time.
    #[inline]
    pub fn edge_vertex(&mut self, p: [u32; 3], dir: u8, make: impl FnOnce() -> u32) -> u32 {
        let i = self.find_or_add(p) as usize;
        let n = self.directions;
        let d = if n == 3 { dir.trailing_zeros() as usize } else { dir as usize - 1 };
        let brick = &mut self.bricks[i];
        if brick.edges.is_empty() {
            brick.edges = vec![u32::MAX; CELLS * n];
            self.edge_bricks += 1;
        }
        let e = &mut brick.edges[slot(p) * n + d];
        if *e == u32::MAX {
            *e = make();
        }
        *e
    }

    /// Cubes visited so far.
    pub fn visited(&self) -> u64 {
        self.visited
    }

    /// Bytes held: the bricks, their edge tables and the index.
    pub fn bytes(&self) -> u64 {
        let edges = self.edge_bricks * (CELLS * self.directions * size_of::<u32>()) as u64;
        let grads = self.grad_bricks * (CELLS * size_of::<[f32; 3]>()) as u64;
        vec_bytes(&self.bricks) + edges + grads + map_bytes(&self.index)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_and_visits_round_trip_across_bricks() {
        let mut l = Lattice::new([100, 50, 20], 7);
        assert!(l.value([3, 4, 5]).is_nan());
        assert!(l.queue([3, 4, 5]));
        assert!(!l.queue([3, 4, 5]));
        assert_eq!(l.value([3, 4, 5]), PENDING);
        for (i, p) in
            [[0, 0, 0], [7, 7, 7], [8, 0, 0], [99, 49, 19], [64, 9, 17]].into_iter().enumerate()
        {
            l.set_value(p, i as f32);
        }
        assert_eq!(l.value([8, 0, 0]), 2.0);
        assert_eq!(l.value([99, 49, 19]), 3.0);
        assert_eq!(l.value([7, 7, 7]), 1.0);
        assert_eq!(l.owner([8, 0, 0]), None);
        l.visit([8, 0, 0], 4);
        l.visit([8, 0, 0], 4);
        assert_eq!(l.owner([8, 0, 0]), Some(4));
        assert_eq!(l.visited(), 1);
        assert_eq!(l.edge_vertex([9, 1, 2], 5, || 42), 42);
        assert_eq!(l.edge_vertex([9, 1, 2], 5, || 43), 42);
        assert_eq!(l.edge_vertex([9, 1, 2], 4, || 44), 44);
        assert!(l.grad([9, 1, 2])[0].is_nan());
        l.set_value_grad([9, 1, 2], -0.5, [1.0, 2.0, 3.0]);
        assert_eq!((l.value([9, 1, 2]), l.grad([9, 1, 2])), (-0.5, [1.0, 2.0, 3.0]));
        assert!(l.grad([9, 1, 3])[0].is_nan());
    }
}
