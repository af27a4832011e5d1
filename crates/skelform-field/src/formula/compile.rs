//! From expressions to a flat register tape.
//!
//! The parser emits nodes straight into a [`Builder`], which keeps them in SSA form (each node
//! refers only to earlier ones), folds constants, applies a few exact rewrites and
//! hash-conses identical nodes, so a repeated subexpression is computed once. [`compile`] then
//! drops nodes the result does not need and assigns registers by liveness (linear scan).

use std::collections::HashMap;
use std::fmt;

use super::ops::{BinOp, UnOp, eval_bin, eval_smin, eval_un};

/// Index of a node in the builder.
pub(crate) type Id = u32;

/// An SSA node. Constants hold their bits so nodes can be hashed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum Node {
    Var(u8),
    Const(u64),
    Unary(UnOp, Id),
    Binary(BinOp, Id, Id),
    /// Polynomial smooth minimum `smin(a, b, k)`; the sharp minimum when `k ≤ 0` or NaN.
    SMin(Id, Id, Id),
}

/// The largest `|n|` for which `u^n` (constant integer `n`) becomes multiplications.
pub(crate) const MAX_INT_POWER: f64 = 64.0;

/// Collects nodes with folding and value numbering.
#[derive(Default)]
pub(crate) struct Builder {
    nodes: Vec<Node>,
    index: HashMap<Node, Id>,
}

impl Builder {
    pub(crate) fn new() -> Self {
        Self::default()
    }

    fn intern(&mut self, node: Node) -> Id {
        if let Some(&id) = self.index.get(&node) {
            return id;
        }
        let id = self.nodes.len() as Id;
        self.nodes.push(node);
        self.index.insert(node, id);
        id
    }

    pub(crate) fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// The value of a node when it is a constant.
    pub(crate) fn constant_value(&self, id: Id) -> Option<f64> {
        match self.nodes[id as usize] {
            Node::Const(bits) => Some(f64::from_bits(bits)),
            _ => None,
        }
    }

    pub(crate) fn num(&mut self, v: f64) -> Id {
        self.intern(Node::Const(v.to_bits()))
    }

    pub(crate) fn var(&mut self, axis: u8) -> Id {
        self.intern(Node::Var(axis))
    }

    pub(crate) fn un(&mut self, op: UnOp, a: Id) -> Id {
        if let Some(c) = self.constant_value(a) {
            return self.num(eval_un(op, c));
        }
        if let (UnOp::Neg, Node::Unary(UnOp::Neg, inner)) = (op, self.nodes[a as usize]) {
            return inner; // -(-u) = u exactly
        }
        self.intern(Node::Unary(op, a))
    }

    pub(crate) fn bin(&mut self, op: BinOp, a: Id, b: Id) -> Id {
        let (ca, cb) = (self.constant_value(a), self.constant_value(b));
        // Before folding: a constant exponent means the same arithmetic whatever the base.
        if let (BinOp::Pow, Some(e)) = (op, cb) {
            return self.pow_const(a, e);
        }
        if let (Some(x), Some(y)) = (ca, cb) {
            return self.num(eval_bin(op, x, y));
        }
        // Exact rewrites only: each gives the same value bit for bit (up to NaN payloads).
        let is = |c: Option<f64>, v: f64| c.is_some_and(|c| c.to_bits() == v.to_bits());
        match op {
            BinOp::Mul | BinOp::Div if is(cb, 1.0) => return a,
            BinOp::Sub if is(cb, 0.0) => return a,
            BinOp::Mul if is(ca, 1.0) => return b,
            BinOp::Mul if is(cb, -1.0) => return self.un(UnOp::Neg, a),
            BinOp::Mul if is(ca, -1.0) => return self.un(UnOp::Neg, b),
            _ => {}
        }
        let (a, b) = if op.commutes() && a > b { (b, a) } else { (a, b) };
        self.intern(Node::Binary(op, a, b))
    }

    /// `u^e` for a constant exponent: `1` for `e = 0`, `u` for `1`, `sqrt(u)` for `0.5`,
    /// repeated multiplication (by squaring) for integers up to [`MAX_INT_POWER`] in magnitude
    /// and `1/u^n` for negative ones; `powf` otherwise.
    fn pow_const(&mut self, a: Id, e: f64) -> Id {
        if e == 0.0 {
            return self.num(1.0);
        }
        if e == 1.0 {
            return a;
        }
        if e == 0.5 {
            return self.un(UnOp::Sqrt, a);
        }
        if e.fract() == 0.0 && e.abs() <= MAX_INT_POWER {
            let mut n = e.abs() as u32;
            let mut result: Option<Id> = None;
            let mut base = a;
            loop {
                if n & 1 == 1 {
                    result = Some(match result {
                        None => base,
                        Some(r) => self.bin(BinOp::Mul, r, base),
                    });
                }
                n >>= 1;
                if n == 0 {
                    break;
                }
                base = self.bin(BinOp::Mul, base, base);
            }
            let r = result.unwrap_or(a);
            return if e < 0.0 {
                let one = self.num(1.0);
                self.bin(BinOp::Div, one, r)
            } else {
                r
            };
        }
        if let Some(x) = self.constant_value(a) {
            return self.num(eval_bin(BinOp::Pow, x, e));
        }
        let c = self.num(e);
        self.intern(Node::Binary(BinOp::Pow, a, c))
    }

    /// Polynomial smooth minimum; a constant `k` that is not positive gives the plain `min`.
    pub(crate) fn smin(&mut self, a: Id, b: Id, k: Id) -> Id {
        match (self.constant_value(a), self.constant_value(b), self.constant_value(k)) {
            (Some(x), Some(y), Some(z)) => self.num(eval_smin(x, y, z)),
            (_, _, Some(z)) if z.is_nan() || z <= 0.0 => self.bin(BinOp::Min, a, b),
            _ => self.intern(Node::SMin(a, b, k)),
        }
    }
}

/// One tape instruction; operands and results are register numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Instr {
    Unary { op: UnOp, out: u32, a: u32 },
    Binary { op: BinOp, out: u32, a: u32, b: u32 },
    SMin { out: u32, a: u32, b: u32, k: u32 },
}

impl Instr {
    fn out(&self) -> u32 {
        match *self {
            Instr::Unary { out, .. } | Instr::Binary { out, .. } | Instr::SMin { out, .. } => out,
        }
    }
}

/// Registers 0, 1, 2 hold x, y, z.
pub(crate) const FIRST_CONST_REG: usize = 3;

/// A compiled formula: instructions over numbered registers.
///
/// Registers 0–2 hold the point's `x, y, z`, the next ones the constants (filled once per
/// evaluation call), and the rest temporaries reused as soon as their value is dead. Every
/// instruction writes a register different from its operands. `Display` prints a listing.
#[derive(Clone, Debug, PartialEq)]
pub struct Tape {
    pub(crate) instrs: Vec<Instr>,
    pub(crate) consts: Vec<f64>,
    pub(crate) n_regs: usize,
    pub(crate) result: u32,
    pub(crate) uses: [bool; 3],
}

impl Tape {
    /// Number of instructions run per point (loads of `x, y, z` and constants not counted).
    pub fn instruction_count(&self) -> usize {
        self.instrs.len()
    }

    /// Number of registers (inputs, constants and temporaries).
    pub fn register_count(&self) -> usize {
        self.n_regs
    }

    /// Number of distinct constants the tape reads.
    pub fn constant_count(&self) -> usize {
        self.consts.len()
    }

    /// The constant value of the formula, when it does not depend on the point.
    pub fn constant_result(&self) -> Option<f64> {
        let r = self.result as usize;
        (r >= FIRST_CONST_REG && r < FIRST_CONST_REG + self.consts.len())
            .then(|| self.consts[r - FIRST_CONST_REG])
    }
}

impl fmt::Display for Tape {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "; {} instructions, {} registers ({} constants)",
            self.instrs.len(),
            self.n_regs,
            self.consts.len()
        )?;
        for (axis, name) in ["x", "y", "z"].iter().enumerate() {
            if self.uses[axis] {
                writeln!(f, "r{axis} = {name}")?;
            }
        }
        for (i, c) in self.consts.iter().enumerate() {
            writeln!(f, "r{} = {c:?}", FIRST_CONST_REG + i)?;
        }
        for ins in &self.instrs {
            match *ins {
                Instr::Unary { op, out, a } => writeln!(f, "r{out} = {} r{a}", op.name())?,
                Instr::Binary { op, out, a, b } => writeln!(f, "r{out} = {} r{a} r{b}", op.name())?,
                Instr::SMin { out, a, b, k } => writeln!(f, "r{out} = smin r{a} r{b} r{k}")?,
            }
        }
        write!(f, "result r{}", self.result)
    }
}

/// A node's operands: the first `n` of the array.
fn operands(node: &Node) -> ([Id; 3], usize) {
    match *node {
        Node::Var(_) | Node::Const(_) => ([0; 3], 0),
        Node::Unary(_, a) => ([a, 0, 0], 1),
        Node::Binary(_, a, b) => ([a, b, 0], 2),
        Node::SMin(a, b, k) => ([a, b, k], 3),
    }
}

/// Turns the nodes that `root` depends on into a tape.
pub(crate) fn compile(nodes: &[Node], root: Id) -> Tape {
    compile_with_slots(nodes, root, &[])
}

/// [`compile`], except that the nodes in `slots` are not computed: their values are loaded
/// by the caller, slot `s` into register `FIRST_CONST_REG + consts.len() + s`, like
/// constants that change between calls.
fn compile_with_slots(nodes: &[Node], root: Id, slots: &[Id]) -> Tape {
    let n = nodes.len();
    let root = root as usize;
    let mut slot = vec![false; n];
    for &id in slots {
        slot[id as usize] = true;
    }
    // Nodes whose registers the instructions do not write.
    let fixed = |i: usize| slot[i] || matches!(nodes[i], Node::Var(_) | Node::Const(_));

    // Liveness: nodes only refer to earlier ones, so one backward sweep marks what is needed.
    let mut live = vec![false; n];
    live[root] = true;
    for i in (0..=root).rev() {
        if live[i] && !slot[i] {
            let (ops, k) = operands(&nodes[i]);
            for &o in &ops[..k] {
                live[o as usize] = true;
            }
        }
    }

    // Fixed registers: inputs, then constants.
    let mut reg = vec![u32::MAX; n];
    let mut uses = [false; 3];
    let mut consts = Vec::new();
    for i in 0..=root {
        if !live[i] || slot[i] {
            continue;
        }
        match nodes[i] {
            Node::Var(axis) => {
                uses[axis as usize] = true;
                reg[i] = axis as u32;
            }
            Node::Const(bits) => {
                reg[i] = (FIRST_CONST_REG + consts.len()) as u32;
                consts.push(f64::from_bits(bits));
            }
            _ => {}
        }
    }

    for (s, &id) in slots.iter().enumerate() {
        reg[id as usize] = (FIRST_CONST_REG + consts.len() + s) as u32;
    }

    // Last reader of each node.
    let mut last_use = vec![usize::MAX; n];
    for i in 0..=root {
        if live[i] && !slot[i] {
            let (ops, k) = operands(&nodes[i]);
            for &o in &ops[..k] {
                last_use[o as usize] = i;
            }
        }
    }

    // Linear scan over temporaries. The result register is taken before the operands that
    // die here are released, so an instruction never overwrites its own inputs.
    let mut free: Vec<u32> = Vec::new();
    let mut next = (FIRST_CONST_REG + consts.len() + slots.len()) as u32;
    let mut instrs = Vec::new();
    for i in 0..=root {
        if !live[i] || fixed(i) {
            continue;
        }
        let out = free.pop().unwrap_or_else(|| {
            next += 1;
            next - 1
        });
        reg[i] = out;
        let r = |id: Id| reg[id as usize];
        instrs.push(match nodes[i] {
            Node::Unary(op, a) => Instr::Unary { op, out, a: r(a) },
            Node::Binary(op, a, b) => Instr::Binary { op, out, a: r(a), b: r(b) },
            Node::SMin(a, b, k) => Instr::SMin { out, a: r(a), b: r(b), k: r(k) },
            Node::Var(_) | Node::Const(_) => unreachable!("filtered above"),
        });
        let (ops, k) = operands(&nodes[i]);
        for (j, &o) in ops[..k].iter().enumerate() {
            let o = o as usize;
            if !fixed(o) && last_use[o] == i && !ops[..j].contains(&(o as Id)) {
                free.push(reg[o]);
            }
        }
    }
    debug_assert!(instrs.iter().all(|ins| (ins.out() as usize) < next as usize));
    Tape { instrs, consts, n_regs: next as usize, result: reg[root], uses }
}

/// Which of a lattice layer's points a value changes between.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Varies {
    /// None: it depends on `z` alone (or on nothing).
    Layer,
    /// Rows: it depends on `y` (and maybe `z`), not on `x`.
    Row,
    /// Columns: it depends on `x` (and maybe `z`), not on `y`.
    Column,
    /// Every point of a layer, but not the layer: it depends on `x` and `y`, not on `z`.
    /// Only a [`Planar`] split has such slots.
    Plane,
}

/// A value computed apart from the points, and loaded into a slot of [`Lattice::point`].
#[derive(Clone, Debug)]
pub(crate) struct Slot {
    pub(crate) varies: Varies,
    pub(crate) tape: Tape,
}

/// A formula split for evaluation over a lattice layer (fixed `z`, rows of fixed `y`, `x`
/// along a row). A term that does not depend on both `x` and `y` takes the same value all
/// along a row, or down a column, so it is computed once per layer, row or column instead
/// of once per point: on the gyroid, `sin(x)`, `cos(y)`, `sin(z)·cos(x)` ... leave the
/// points, which keep one product and two sums. The same operations on the same inputs:
/// the values are the point-by-point ones, bit for bit.
#[derive(Clone, Debug)]
pub(crate) struct Lattice {
    /// The per-point part; slot `s` is [`Lattice::slots`]`[s]`.
    pub(crate) point: Tape,
    pub(crate) slots: Vec<Slot>,
}

/// A formula split for evaluation over many layers of one lattice: besides [`Lattice`]'s
/// slots, terms of `x` and `y` alone (the torus's `(sqrt(x² + y²) − R)²`) are computed once
/// for all layers, at every point of the plane.
#[derive(Clone, Debug)]
pub(crate) struct Planar {
    /// Its [`Varies::Plane`] slots are filled from a cache of the plane's values.
    pub(crate) lattice: Lattice,
    /// How to compute each [`Varies::Plane`] slot over the plane, in slot order.
    pub(crate) planes: Vec<Lattice>,
}

/// The axes (bit 0: x, 1: y, 2: z) each node up to `root` depends on.
fn axes_of(nodes: &[Node], root: usize) -> Vec<u8> {
    let mut axes = vec![0u8; root + 1];
    for i in 0..=root {
        axes[i] = match nodes[i] {
            Node::Var(axis) => 1 << axis,
            _ => {
                let (ops, k) = operands(&nodes[i]);
                ops[..k].iter().fold(0, |m, &o| m | axes[o as usize])
            }
        };
    }
    axes
}

/// Splits the formula rooted at `root` for lattice evaluation, one layer at a time.
pub(crate) fn lattice(nodes: &[Node], root: Id) -> Lattice {
    split(nodes, root, false).0
}

/// Splits the formula rooted at `root` for many layers of one lattice; `None` when no term
/// depends on `x` and `y` alone (then [`lattice`]'s split does as well).
pub(crate) fn planar(nodes: &[Node], root: Id) -> Option<Planar> {
    let (lattice, ids) = split(nodes, root, true);
    let planes: Vec<Lattice> = lattice
        .slots
        .iter()
        .zip(ids)
        .filter(|(slot, _)| slot.varies == Varies::Plane)
        .map(|(_, id)| split(nodes, id, false).0)
        .collect();
    (!planes.is_empty()).then_some(Planar { lattice, planes })
}

/// From the root down through per-point nodes; the first other node on each path is a slot
/// (what it depends on is the slot's own business). Per point: what depends on `x` and `y`
/// (and, with `planes`, on `z` too).
fn slot_roots(nodes: &[Node], root: usize, axes: &[u8], planes: bool) -> Vec<Id> {
    let per_point = |i: usize| {
        let a = axes[i];
        a & 3 == 3 && (!planes || a & 4 != 0)
    };
    let leaf = |i: usize| matches!(nodes[i], Node::Var(_) | Node::Const(_));
    let mut reached = vec![false; root + 1];
    let mut slots = Vec::new();
    reached[root] = true;
    for i in (0..=root).rev() {
        if !reached[i] || leaf(i) {
            continue;
        }
        if !per_point(i) {
            slots.push(i as Id);
            continue;
        }
        let (ops, k) = operands(&nodes[i]);
        for &o in &ops[..k] {
            reached[o as usize] = true;
        }
    }
    slots.reverse();
    slots
}

/// The split, and the node of each slot.
fn split(nodes: &[Node], root: Id, planes: bool) -> (Lattice, Vec<Id>) {
    let axes = axes_of(nodes, root as usize);
    let ids = slot_roots(nodes, root as usize, &axes, planes);
    let point = compile_with_slots(nodes, root, &ids);
    let slots = ids
        .iter()
        .map(|&id| {
            let a = axes[id as usize];
            let varies = match (a & 1 != 0, a & 2 != 0) {
                (true, true) => Varies::Plane,
                (true, false) => Varies::Column,
                (false, true) => Varies::Row,
                (false, false) => Varies::Layer,
            };
            Slot { varies, tape: compile(nodes, id) }
        })
        .collect();
    (Lattice { point, slots }, ids)
}
