//! Running a tape: values, and values with gradients by forward-mode differentiation.
//!
//! The batch interpreters run one instruction at a time over `L` lanes (one tight loop per
//! instruction, which the compiler vectorises; with AVX2 where the CPU has it). The
//! single-point paths use the same lane functions (values through a scalar interpreter,
//! gradients through the dual interpreter with `L = 1`), so a point gives bit-identical
//! results whichever way it is evaluated. Nothing allocates per point: registers live on the
//! stack (single points) or in a per-thread cache (batches).

use std::cell::RefCell;
use std::ops::Range;
use std::thread::LocalKey;

use glam::DVec3;

use super::compile::{FIRST_CONST_REG, Instr, Lattice, Planar, Tape, Varies};
use super::ops::{
    UnOp, eval_bin, eval_un, lane, smin_ad, with_binary, with_binary_ad, with_unary, with_unary_ad,
};
use super::trig;
use crate::LayerSampler;

/// Lanes per batch for values: 128 × 8 bytes = 1 KiB per register.
pub(crate) const LANES: usize = 128;
/// Lanes per batch for values with gradients: 64 × 4 × 8 bytes = 2 KiB per register.
pub(crate) const AD_LANES: usize = 64;
/// Registers kept on the stack by the single-point paths; larger tapes use a thread-local.
const STACK_REGS: usize = 48;

/// One chain-rule term `f · t`, taken as 0 when either factor is 0, so a local derivative
/// that is infinite or NaN (sqrt at 0, ln at 0, the unselected side of a min) does not spoil a
/// gradient it does not contribute to.
#[inline(always)]
fn tm(f: f64, t: f64) -> f64 {
    if f == 0.0 || t == 0.0 { 0.0 } else { f * t }
}

/// Borrows register `out` mutably and the others shared; `out` differs from every operand
/// (the register allocator guarantees it).
#[inline(always)]
fn split<T, const N: usize>(regs: &mut [T], out: u32, ins: [u32; N]) -> (&mut T, [&T; N]) {
    let out = out as usize;
    let (lo, rest) = regs.split_at_mut(out);
    let (o, hi) = rest.split_first_mut().expect("register out of range");
    let hi: &[T] = hi;
    let lo: &[T] = lo;
    let get = |i: u32| {
        let i = i as usize;
        debug_assert_ne!(i, out, "an instruction overwrites its operand");
        if i < out { &lo[i] } else { &hi[i - out - 1] }
    };
    (o, ins.map(get))
}

/// Runs the tape's instructions over the first `n` lanes of every register. Inputs and
/// constants must already be loaded.
#[inline(always)]
fn run_values<const L: usize>(tape: &Tape, regs: &mut [[f64; L]], n: usize) {
    let n = n.min(L);
    for ins in &tape.instrs {
        match *ins {
            Instr::Unary { op, out, a } => {
                let (o, [a]) = split(regs, out, [a]);
                match op {
                    UnOp::Sin => trig_batch(&mut o[..n], &a[..n], trig::sin, f64::sin),
                    UnOp::Cos => trig_batch(&mut o[..n], &a[..n], trig::cos, f64::cos),
                    _ => with_unary!(op, f => {
                        for i in 0..n {
                            o[i] = f(a[i]);
                        }
                    }),
                }
            }
            Instr::Binary { op, out, a, b } => {
                let (o, [a, b]) = split(regs, out, [a, b]);
                with_binary!(op, f => {
                    for i in 0..n {
                        o[i] = f(a[i], b[i]);
                    }
                })
            }
            Instr::SMin { out, a, b, k } => {
                let (o, [a, b, k]) = split(regs, out, [a, b, k]);
                for i in 0..n {
                    o[i] = lane::smin(a[i], b[i], k[i]);
                }
            }
        }
    }
}

/// Wider vectors where the CPU has them. The instructions are the same IEEE operations
/// (no fused multiply-add: Rust never contracts `a * b + c`), so the results are
/// bit-identical to the baseline build and to the single-point path.
#[cfg(target_arch = "x86_64")]
mod wide {
    use super::{Dual, Tape};

    pub(super) fn available() -> bool {
        std::arch::is_x86_feature_detected!("avx2")
    }

    /// # Safety
    /// The CPU must support AVX2 ([`available`]).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn run_values<const L: usize>(tape: &Tape, regs: &mut [[f64; L]], n: usize) {
        super::run_values(tape, regs, n)
    }

    /// # Safety
    /// The CPU must support AVX2 ([`available`]).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn run_duals<const L: usize>(tape: &Tape, regs: &mut [Dual<L>], n: usize) {
        super::run_duals(tape, regs, n)
    }
}

/// [`run_values`] for batches, with the widest vectors available.
fn run_values_batch<const L: usize>(tape: &Tape, regs: &mut [[f64; L]], n: usize) {
    #[cfg(target_arch = "x86_64")]
    if wide::available() {
        // SAFETY: AVX2 was detected at run time.
        unsafe { wide::run_values(tape, regs, n) };
        return;
    }
    run_values(tape, regs, n)
}

/// [`run_duals`] for batches, with the widest vectors available.
fn run_duals_batch<const L: usize>(tape: &Tape, regs: &mut [Dual<L>], n: usize) {
    #[cfg(target_arch = "x86_64")]
    if wide::available() {
        // SAFETY: AVX2 was detected at run time.
        unsafe { wide::run_duals(tape, regs, n) };
        return;
    }
    run_duals(tape, regs, n)
}

/// `lane::sin`/`lane::cos` over a batch: the branch-free kernel on every lane (vectorised),
/// then the libm function on the rare lanes out of its range.
#[inline(always)]
fn trig_batch(o: &mut [f64], a: &[f64], fast: fn(f64) -> f64, slow: fn(f64) -> f64) {
    for (o, &a) in o.iter_mut().zip(a) {
        *o = fast(a);
    }
    for (o, &a) in o.iter_mut().zip(a) {
        if a.abs() > trig::FAST_MAX || a.is_nan() {
            *o = slow(a);
        }
    }
}

/// A register of the differentiating interpreter: values and the three partials per lane.
#[derive(Clone, Copy)]
pub(crate) struct Dual<const L: usize> {
    v: [f64; L],
    d: [[f64; L]; 3],
}

impl<const L: usize> Dual<L> {
    const ZERO: Self = Self { v: [0.0; L], d: [[0.0; L]; 3] };
}

#[inline(always)]
fn run_duals<const L: usize>(tape: &Tape, regs: &mut [Dual<L>], n: usize) {
    let n = n.min(L);
    for ins in &tape.instrs {
        match *ins {
            Instr::Unary { op: op @ (UnOp::Sin | UnOp::Cos), out, a } => {
                // Value and derivative from the vectorised kernels (same values as `lane`).
                let (o, [a]) = split(regs, out, [a]);
                let mut deriv = [0.0; L];
                if op == UnOp::Sin {
                    trig_batch(&mut o.v[..n], &a.v[..n], trig::sin, f64::sin);
                    trig_batch(&mut deriv[..n], &a.v[..n], trig::cos, f64::cos);
                } else {
                    trig_batch(&mut o.v[..n], &a.v[..n], trig::cos, f64::cos);
                    trig_batch(&mut deriv[..n], &a.v[..n], trig::sin, f64::sin);
                    deriv[..n].iter_mut().for_each(|d| *d = -*d);
                }
                for (od, ad) in o.d.iter_mut().zip(&a.d) {
                    for ((o, &d), &t) in od[..n].iter_mut().zip(&deriv[..n]).zip(&ad[..n]) {
                        *o = tm(d, t);
                    }
                }
            }
            Instr::Unary { op, out, a } => {
                let (o, [a]) = split(regs, out, [a]);
                with_unary_ad!(op, g => {
                    for i in 0..n {
                        let (v, fa) = g(a.v[i]);
                        o.v[i] = v;
                        for c in 0..3 {
                            o.d[c][i] = tm(fa, a.d[c][i]);
                        }
                    }
                })
            }
            Instr::Binary { op, out, a, b } => {
                let (o, [a, b]) = split(regs, out, [a, b]);
                with_binary_ad!(op, g => {
                    for i in 0..n {
                        let (v, fa, fb) = g(a.v[i], b.v[i]);
                        o.v[i] = v;
                        for c in 0..3 {
                            o.d[c][i] = tm(fa, a.d[c][i]) + tm(fb, b.d[c][i]);
                        }
                    }
                })
            }
            Instr::SMin { out, a, b, k } => {
                let (o, [a, b, k]) = split(regs, out, [a, b, k]);
                for i in 0..n {
                    let (v, fa, fb, fk) = smin_ad(a.v[i], b.v[i], k.v[i]);
                    o.v[i] = v;
                    for c in 0..3 {
                        o.d[c][i] = tm(fa, a.d[c][i]) + tm(fb, b.d[c][i]) + tm(fk, k.d[c][i]);
                    }
                }
            }
        }
    }
}

thread_local! {
    static VALUE_SCRATCH: RefCell<Vec<[f64; LANES]>> = const { RefCell::new(Vec::new()) };
    static DUAL_SCRATCH: RefCell<Vec<Dual<AD_LANES>>> = const { RefCell::new(Vec::new()) };
    static POINT_SCRATCH: RefCell<Vec<[f64; 1]>> = const { RefCell::new(Vec::new()) };
    static POINT_DUAL_SCRATCH: RefCell<Vec<Dual<1>>> = const { RefCell::new(Vec::new()) };
}

/// Runs `f` on `len` registers from the thread's cache (or fresh ones when the cache is busy
/// or gone), so evaluation does not allocate once a thread has warmed up.
fn with_scratch<T: Copy + 'static, R>(
    key: &'static LocalKey<RefCell<Vec<T>>>,
    len: usize,
    fill: T,
    f: impl FnOnce(&mut [T]) -> R,
) -> R {
    let mut f = Some(f);
    let cached = key.try_with(|cell| {
        let mut regs = cell.try_borrow_mut().ok()?;
        if regs.len() < len {
            regs.resize(len, fill);
        }
        let f = f.take()?;
        Some(f(&mut regs[..len]))
    });
    match (cached, f) {
        (Ok(Some(r)), _) => r,
        (_, Some(f)) => f(&mut vec![fill; len]),
        (_, None) => unreachable!("the closure ran but gave no result"),
    }
}

/// Loads the inputs and constants, runs the tape and returns the result register's value.
fn point_values(tape: &Tape, p: DVec3, regs: &mut [[f64; 1]]) -> f64 {
    regs[0] = [p.x];
    regs[1] = [p.y];
    regs[2] = [p.z];
    for (r, &c) in regs[FIRST_CONST_REG..].iter_mut().zip(&tape.consts) {
        *r = [c];
    }
    run_scalar(tape, regs.as_flattened_mut());
    regs[tape.result as usize][0]
}

/// The single-point interpreter: the same lane functions as [`run_values`] (so the same
/// bits), without the batch machinery.
fn run_scalar(tape: &Tape, r: &mut [f64]) {
    for ins in &tape.instrs {
        match *ins {
            Instr::Unary { op, out, a } => r[out as usize] = eval_un(op, r[a as usize]),
            Instr::Binary { op, out, a, b } => {
                r[out as usize] = eval_bin(op, r[a as usize], r[b as usize])
            }
            Instr::SMin { out, a, b, k } => {
                r[out as usize] = lane::smin(r[a as usize], r[b as usize], r[k as usize]);
            }
        }
    }
}

pub(crate) fn eval_point(tape: &Tape, p: DVec3) -> f64 {
    if tape.n_regs <= STACK_REGS {
        let mut regs = [[0.0; 1]; STACK_REGS];
        point_values(tape, p, &mut regs[..tape.n_regs])
    } else {
        with_scratch(&POINT_SCRATCH, tape.n_regs, [0.0; 1], |regs| point_values(tape, p, regs))
    }
}

pub(crate) fn eval_batch(tape: &Tape, points: &[DVec3], out: &mut [f64]) {
    let m = points.len().min(out.len());
    let (points, out) = (&points[..m], &mut out[..m]);
    if m == 0 {
        return;
    }
    with_scratch(&VALUE_SCRATCH, tape.n_regs, [0.0; LANES], |regs| {
        for (r, &c) in regs[FIRST_CONST_REG..].iter_mut().zip(&tape.consts) {
            *r = [c; LANES];
        }
        let result = tape.result as usize;
        for (pts, outs) in points.chunks(LANES).zip(out.chunks_mut(LANES)) {
            let n = pts.len();
            {
                let [xs, ys, zs, ..] = regs else {
                    unreachable!("a tape has at least 3 registers")
                };
                for (i, p) in pts.iter().enumerate() {
                    xs[i] = p.x;
                    ys[i] = p.y;
                    zs[i] = p.z;
                }
            }
            run_values_batch(tape, regs, n);
            outs.copy_from_slice(&regs[result][..n]);
        }
    })
}

/// Values on a lattice layer, `out[i + xs.len()·j] = f(xs[i], ys[j], z)`, with the terms
/// that depend on fewer axes computed once per layer, row or column ([`Lattice`]).
pub(crate) fn eval_layer(lattice: &Lattice, xs: &[f64], ys: &[f64], z: f64, out: &mut [f64]) {
    run_layer(lattice, xs, ys, z, &[], out)
}

/// [`eval_layer`] for a split with [`Varies::Plane`] slots: `planes[p]` holds the `p`-th
/// such slot's values at the same points (`xs.len()·ys.len()` each, rows as in `out`).
pub(crate) fn run_layer(
    lattice: &Lattice,
    xs: &[f64],
    ys: &[f64],
    z: f64,
    planes: &[&[f64]],
    out: &mut [f64],
) {
    let nx = xs.len();
    let (Some(&x0), Some(&y0)) = (xs.first(), ys.first()) else { return };
    let mut planes = planes.iter();
    // Where each slot's values come from. Down a column the value is the same, so the first
    // row's points will do; along a row, the first column's.
    let loads: Vec<Load> = lattice
        .slots
        .iter()
        .map(|slot| match slot.varies {
            Varies::Layer => Load::Layer(eval_point(&slot.tape, DVec3::new(x0, y0, z))),
            Varies::Row => Load::Row(
                ys.iter().map(|&y| eval_point(&slot.tape, DVec3::new(x0, y, z))).collect(),
            ),
            Varies::Column => {
                let points: Vec<DVec3> = xs.iter().map(|&x| DVec3::new(x, y0, z)).collect();
                let mut values = vec![0.0; nx];
                eval_batch(&slot.tape, &points, &mut values);
                Load::Column(values)
            }
            Varies::Plane => Load::Plane(planes.next().expect("a plane's values for each slot")),
        })
        .collect();
    let point = &lattice.point;
    let first_slot = FIRST_CONST_REG + point.consts.len();
    with_scratch(&VALUE_SCRATCH, point.n_regs, [0.0; LANES], |regs| {
        for (r, &c) in regs[FIRST_CONST_REG..].iter_mut().zip(&point.consts) {
            *r = [c; LANES];
        }
        regs[2] = [z; LANES];
        for (s, load) in loads.iter().enumerate() {
            if let Load::Layer(v) = *load {
                regs[first_slot + s] = [v; LANES];
            }
        }
        // A stretch of columns at a time, down all the rows: the column terms are loaded
        // once per stretch, the row terms (a broadcast) and plane terms once per row.
        for at in (0..nx).step_by(LANES) {
            let n = LANES.min(nx - at);
            regs[0][..n].copy_from_slice(&xs[at..at + n]);
            for (s, load) in loads.iter().enumerate() {
                if let Load::Column(column) = load {
                    regs[first_slot + s][..n].copy_from_slice(&column[at..at + n]);
                }
            }
            for (j, &y) in ys.iter().enumerate() {
                regs[1] = [y; LANES];
                for (s, load) in loads.iter().enumerate() {
                    match load {
                        Load::Row(row) => regs[first_slot + s] = [row[j]; LANES],
                        Load::Plane(plane) => {
                            regs[first_slot + s][..n].copy_from_slice(&plane[j * nx + at..][..n])
                        }
                        Load::Layer(_) | Load::Column(_) => {}
                    }
                }
                run_values_batch(point, regs, n);
                out[j * nx + at..][..n].copy_from_slice(&regs[point.result as usize][..n]);
            }
        }
    })
}

/// The layers of one lattice, the plane slots' values computed once.
pub(crate) struct Sampler<'a> {
    lattice: &'a Lattice,
    xs: Vec<f64>,
    ys: Vec<f64>,
    /// Per [`Varies::Plane`] slot, its values at every `(x, y)`, x fastest.
    planes: Vec<Vec<f64>>,
}

impl<'a> Sampler<'a> {
    pub(crate) fn with_planes(planar: &'a Planar, xs: Vec<f64>, ys: Vec<f64>) -> Self {
        let planes = planar
            .planes
            .iter()
            .map(|plane| {
                let mut values = vec![0.0; xs.len() * ys.len()];
                // The term does not depend on z: any layer gives its values.
                eval_layer(plane, &xs, &ys, 0.0, &mut values);
                values
            })
            .collect();
        Sampler { lattice: &planar.lattice, xs, ys, planes }
    }

    /// For a split without plane slots ([`Lattice`]).
    pub(crate) fn without_planes(lattice: &'a Lattice, xs: Vec<f64>, ys: Vec<f64>) -> Self {
        Sampler { lattice, xs, ys, planes: Vec::new() }
    }
}

impl LayerSampler for Sampler<'_> {
    fn layer(&self, z: f64, rows: Range<usize>, out: &mut [f64]) {
        let nx = self.xs.len();
        let planes: Vec<&[f64]> =
            self.planes.iter().map(|p| &p[rows.start * nx..rows.end * nx]).collect();
        run_layer(self.lattice, &self.xs, &self.ys[rows], z, &planes, out)
    }
}

/// Where a lattice slot's values come from, in [`run_layer`].
enum Load<'a> {
    Layer(f64),
    Row(Vec<f64>),
    Column(Vec<f64>),
    Plane(&'a [f64]),
}

/// Seeds the inputs (`∂x/∂x = 1`, ...) and constants (zero partials) of dual registers.
fn seed<const L: usize>(tape: &Tape, regs: &mut [Dual<L>]) {
    for (axis, r) in regs[..FIRST_CONST_REG].iter_mut().enumerate() {
        *r = Dual::ZERO;
        r.d[axis] = [1.0; L];
    }
    for (r, &c) in regs[FIRST_CONST_REG..].iter_mut().zip(&tape.consts) {
        *r = Dual { v: [c; L], d: [[0.0; L]; 3] };
    }
}

fn point_duals(tape: &Tape, p: DVec3, regs: &mut [Dual<1>]) -> (f64, DVec3) {
    seed(tape, regs);
    regs[0].v = [p.x];
    regs[1].v = [p.y];
    regs[2].v = [p.z];
    run_duals(tape, regs, 1);
    let r = &regs[tape.result as usize];
    (r.v[0], DVec3::new(r.d[0][0], r.d[1][0], r.d[2][0]))
}

pub(crate) fn grad_point(tape: &Tape, p: DVec3) -> (f64, DVec3) {
    if tape.n_regs <= STACK_REGS {
        let mut regs = [Dual::<1>::ZERO; STACK_REGS];
        point_duals(tape, p, &mut regs[..tape.n_regs])
    } else {
        with_scratch(&POINT_DUAL_SCRATCH, tape.n_regs, Dual::ZERO, |regs| {
            point_duals(tape, p, regs)
        })
    }
}

pub(crate) fn grad_batch(tape: &Tape, points: &[DVec3], values: &mut [f64], grads: &mut [DVec3]) {
    let m = points.len().min(values.len()).min(grads.len());
    let (points, values, grads) = (&points[..m], &mut values[..m], &mut grads[..m]);
    if m == 0 {
        return;
    }
    with_scratch(&DUAL_SCRATCH, tape.n_regs, Dual::ZERO, |regs| {
        seed(tape, regs);
        let result = tape.result as usize;
        let chunks = points
            .chunks(AD_LANES)
            .zip(values.chunks_mut(AD_LANES))
            .zip(grads.chunks_mut(AD_LANES));
        for ((pts, vals), gs) in chunks {
            let n = pts.len();
            for (i, p) in pts.iter().enumerate() {
                regs[0].v[i] = p.x;
                regs[1].v[i] = p.y;
                regs[2].v[i] = p.z;
            }
            run_duals_batch(tape, regs, n);
            let r = &regs[result];
            vals.copy_from_slice(&r.v[..n]);
            for (i, g) in gs.iter_mut().enumerate() {
                *g = DVec3::new(r.d[0][i], r.d[1][i], r.d[2][i]);
            }
        }
    })
}
