//! A tube through one cube's interior (MC33 4.1.2, 6.1.2, 7.4.2, 10.1.2, 12.1.2, 13.5.2),
//! built so that it cannot cross itself.
//!
//! Why it is embedded: the tube is a *radial graph* seen from a centre `c` inside the cube
//! (the saddle, or a point on the saddle's axis still on the tube's side; at least [`INSET`]
//! from every face, the saddle moved in where it lies nearer one). The two loops lie
//! on the cube's boundary, which is convex with `c` inside, so seen from `c` they are two
//! disjoint simple closed curves on the sphere of directions (each loop segment, lying in a
//! face, is seen as an arc of a great circle). Between them lies an annulus of directions in
//! which the ray from `c` leaves the tube (it starts on the tube's side and ends on the
//! cube's boundary on the other side). The ring's vertices lie on rays through that annulus,
//! where each meets the interpolant's level set, and the triangles are chosen so that, seen
//! from `c`, every one turns the same way (`orient(c, p, q, r)` has the tube's sign).
//! Triangles that all turn one way seen from one point, bounded by the two loops, cover the
//! annulus of directions once, plus the whole sphere once for each extra turn round `c` (the
//! loops fix the cover only up to whole turns); when their solid angles add up to less than
//! the sphere there is none: no ray from `c` meets two of them, so no two cross. Sliding a
//! ring vertex along its ray (refinement does) turns nothing over and changes no solid angle.
//!
//! The search: rings on the meridians of an axis (halfway, in angle from the axis, between
//! where each half-plane through the axis meets the two loops) and rings in a plane through
//! `c` that separates the loops; axes between the loops' mean directions, along the saddle's
//! Hessian eigenvector of the odd sign, and between the loops' centroids; each band zipped in
//! order of angle round whichever axis turns none of its triangles the wrong way. The first
//! plan with every triangle turned right and no extra turn, every ring vertex on the level
//! set, loop vertices that can each move [`ENOUGH`] cells before a triangle turns over
//! (refinement moves them along their cube edges, by a fraction of a cell) and ring vertices
//! [`RING_CLEARANCE`] clear of turning one over (what rounding moves them off their rays)
//! is kept, else the best.
//! (A ring shaped like one loop, zipped by distance, as before, crossed itself in about a
//! third of random tube cubes: with a thin tube the ring is tiny, and the distances from a
//! loop's vertices to it no longer tell which way round it lies.)

use glam::DVec3;

use super::cell::CubeSink;
use super::extract::Slide;
use super::interior::{level_on_ray, level_on_ray_to, saddle_axis, trilinear};

/// The clearance (in cells: how far every loop vertex can move before one of its triangles
/// turns over seen from the centre) at which the search for a tube stops. The 24 random
/// fields of `tests/interior_vertices.rs` cross after refinement with 0.05.
const ENOUGH: f64 = 0.1;

/// The least distance (in cells) of a tube's centre from the cube's faces. A saddle on the
/// cube's boundary (at the level where the face's own saddle is, or on an edge, in cubes
/// with exactly representable values) sees the loop segments in its face edge on: their
/// triangles turn neither way, and rays leaving through that face leave at once, so the
/// ring vertices on them collapse onto the centre; the tube then crossed itself.
const INSET: f64 = 0.02;

#[cfg(test)]
thread_local! {
    /// Plans made (rings placed), for tests that count the work per tube.
    pub static PLANS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
    /// Tubes kept with a triangle that does not turn the right way seen from the centre
    /// (the search found no plan without one; the tube may then cross itself).
    pub static FLAWED: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// The clearance (in cells) a ring vertex needs from the plane through the centre and its
/// triangle's other two vertices before a plan counts as good: enough for the triangle to
/// turn the same way seen from the centre once the vertex has left its exact ray.
///
/// Why it can leave it: refinement slides a ring vertex along its stored line, which is
/// rounded to [`SLIDE_UNIT`](super::extract::SLIDE_UNIT) per component, so the centre it
/// slides from is off by up to `½·√3·2⁻¹⁴ ≈ 5.3e-5` cells, and sliding to the fraction
/// `t` of its distance moves it off the ray by `|1 − t|` of that; the mesh is then
/// written in `f32`, which rounds each coordinate of a grid within 2¹⁰ cells of the origin
/// by up to `2⁻¹⁵` cells, `5.3e-5` cells as a vector. A triangle keeps its turn while each
/// vertex moves less than its clearance (shared among its two ring vertices: half each),
/// and the clearance shrinks with the slide: sliding in to `RING_KEEP = 0.1` of the
/// distance (`grid::cell_line`) needs `0.1·c ≥ 2·(0.9 + 1)·5.3e-5`, `c ≥ 2e-3` cells.
/// Ring vertices 1e-3 cells from the centre (a saddle at the level: [`MIN_RING`]) cannot
/// clear that; the search then goes on to centres off the saddle, whose rings are wide.
/// (Before, with no margin, 9 of 600 tubes pinched at their saddle turned a triangle over
/// seen from the centre when slid and rounded so: `grid::interior`'s
/// `tube_triangles_keep_their_turn_when_refined_and_written_in_f32`.)
const RING_CLEARANCE: f64 = 2e-3;

/// The least distance (in cells) of a ring vertex from its tube's centre: where the
/// interpolant's level set passes through the saddle (a saddle value of zero, up to
/// rounding), its ring would shrink to a point and its triangles to slivers.
const MIN_RING: f64 = 1e-3;

/// One loop vertex: the sink's id and its position in the cube.
pub type LoopVertex = (u32, [f64; 3]);

/// Emits a tube from loop `a` through a ring round the saddle `s` to loop `b`, both loops
/// oriented as the boundaries of the disks the tube replaces. `inside` tells the tube's
/// side (`f < 0` inside it), which fixes the way its triangles turn seen from the centre:
/// away from it for an inside tube, towards it otherwise. Ring vertices go to the sink with
/// their rays from the centre as their [`Slide`].
pub fn build(
    v: &[f32; 8],
    s: [f64; 3],
    inside: bool,
    a: &[LoopVertex],
    b: &[LoopVertex],
    sink: &mut impl CubeSink,
) {
    let sv = DVec3::from_array(s);
    let sign = if inside { 1.0 } else { -1.0 };
    let at =
        |l: &[LoopVertex]| -> Vec<DVec3> { l.iter().map(|x| DVec3::from_array(x.1)).collect() };
    let (pa, pb) = (at(a), at(b));
    if pa.is_empty() || pb.is_empty() {
        return;
    }
    let centroid = |ps: &[DVec3]| ps.iter().sum::<DVec3>() / ps.len() as f64;
    let joining = centroid(&pa) - centroid(&pb);
    let mut hessian = DVec3::from_array(saddle_axis(v, s));
    if hessian.dot(joining) < 0.0 {
        hessian = -hessian;
    }
    let n = pa.len().max(pb.len());
    let mut best: Option<Plan> = None;
    // The first centre is the saddle, moved [`INSET`] inside the cube if it lies nearer a
    // face: seen from a point on a face, the loop segments in that face are seen edge on
    // and the triangles through them turn neither way.
    let base = sv.clamp(DVec3::splat(INSET), DVec3::splat(1.0 - INSET));
    'search: for step in [0.0, 0.1, -0.1, 0.2, -0.2, 0.3, -0.3] {
        let c = base + hessian * step;
        if step != 0.0
            && (c.min_element() < INSET
                || c.max_element() > 1.0 - INSET
                || (trilinear(v, c.to_array()) < 0.0) != inside)
        {
            continue;
        }
        let mean_dir = |ps: &[DVec3]| {
            ps.iter().map(|&p| (p - c).normalize_or_zero()).sum::<DVec3>().normalize_or_zero()
        };
        let (ca, cb) = (mean_dir(&pa), mean_dir(&pb));
        let mut axes: Vec<DVec3> = [ca - cb, hessian, joining]
            .iter()
            .map(|u| u.normalize_or_zero())
            .filter(|u| *u != DVec3::ZERO)
            .collect();
        if axes.is_empty() {
            axes.push(DVec3::X); // some plan, so that the tube is never left out
        }
        let mut band_axes = axes.clone();
        band_axes.extend([ca, cb].iter().filter(|u| **u != DVec3::ZERO));
        // Rings: through the middle of the annulus of directions between the loops, on the
        // meridians of each axis; then in each plane through `c` that separates the loops.
        let meridian = axes.iter().map(|&u| meridian_ring(c, u, sign, &pa, &pb, n));
        let plane = axes.iter().filter_map(|&w| {
            let separates = pa.iter().all(|&p| (p - c).dot(w) > 1e-9)
                && pb.iter().all(|&p| (p - c).dot(w) < -1e-9);
            separates.then(|| plane_ring(c, w, sign, &pa, n))
        });
        for dirs in meridian.chain(plane) {
            let mut off = 0;
            let ring: Vec<DVec3> = dirs
                .iter()
                .map(|&d| {
                    let (p, on) = ray_point(v, c, d);
                    off += usize::from(!on);
                    p
                })
                .collect();
            let plan = Plan::new(c, sign, &pa, &pb, ring, &band_axes, off);
            #[cfg(test)]
            PLANS.with(|p| p.set(p.get() + 1));
            if best.as_ref().is_none_or(|b| plan.flaws() < b.flaws()) {
                best = Some(plan);
            }
            if best.as_ref().is_some_and(|b| b.wrong == 0 && b.off == 0 && b.margin >= ENOUGH) {
                break 'search;
            }
        }
    }
    let Some(plan) = best else {
        return;
    };
    #[cfg(test)]
    FLAWED.with(|f| f.set(f.get() + u64::from(plan.wrong > 0)));
    let ring: Vec<u32> = plan
        .ring
        .iter()
        .map(|&p| {
            let c = plan.centre;
            let p = level_on_ray(v, c.to_array(), (p - c).to_array())
                .map(DVec3::from_array)
                .filter(|q| q.distance(c) >= MIN_RING)
                .unwrap_or(p);
            let line = (p - c).to_array();
            sink.cell_vertex(p.to_array(), Slide { line, ray: true })
        })
        .collect();
    let id = |v: Vert| match v {
        Vert::A(i) => a[i].0,
        Vert::B(i) => b[i].0,
        Vert::Ring(i) => ring[i],
    };
    for t in &plan.tris {
        sink.triangle(t.map(id));
    }
}

/// A tube vertex: of loop `a`, of loop `b`, or of the ring.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Vert {
    A(usize),
    B(usize),
    Ring(usize),
}

/// The tube for one axis: ring positions, triangles, and how many triangles turn the wrong
/// way seen from the saddle.
struct Plan {
    centre: DVec3,
    ring: Vec<DVec3>,
    tris: Vec<[Vert; 3]>,
    wrong: usize,
    off: usize,
    /// The least distance (in cells) of a triangle's vertex from the plane through the
    /// centre and the other two, on the side that turns it the right way: how far the loop
    /// vertices can move (refinement moves them along the cube's edges) before a triangle
    /// could turn over; ring vertices' distances scaled by `ENOUGH / RING_CLEARANCE`.
    margin: f64,
}

/// The angle of `d` round the axis in the frame `(e1, e2)`.
fn angle(d: DVec3, e1: DVec3, e2: DVec3) -> f64 {
    d.dot(e2).atan2(d.dot(e1))
}

/// The signed solid angle of the triangle `d` (vertices relative to the viewpoint), positive
/// where it turns counter-clockwise seen from it (Van Oosterom and Strackee).
fn solid_angle(d: [DVec3; 3]) -> f64 {
    let [a, b, c] = d;
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    2.0 * a.dot(b.cross(c)).atan2(den)
}

/// `x` reduced to `(-π, π]`.
fn wrap(x: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let r = x.rem_euclid(TAU);
    if r > PI { r - TAU } else { r }
}

/// Angles round the axis along a closed polygon, unwrapped so that each step turns by less
/// than half a turn: `n + 1` values, the last the first's plus the polygon's winding.
fn unwrapped(ps: &[DVec3], s: DVec3, e1: DVec3, e2: DVec3) -> Vec<f64> {
    let mut out = Vec::with_capacity(ps.len() + 1);
    let first = angle(ps[0] - s, e1, e2);
    out.push(first);
    let mut last = first;
    let mut acc = first;
    for k in 1..=ps.len() {
        let a = angle(ps[k % ps.len()] - s, e1, e2);
        acc += wrap(a - last);
        last = a;
        out.push(acc);
    }
    out
}

/// The polar angles (from `u`) at which the half-plane through the axis towards `w` meets
/// the closed polygon `ps`.
fn meridian_hits(ps: &[DVec3], s: DVec3, u: DVec3, w: DVec3) -> impl Iterator<Item = f64> + '_ {
    let n = u.cross(w);
    (0..ps.len()).filter_map(move |k| {
        let (p, q) = (ps[k] - s, ps[(k + 1) % ps.len()] - s);
        let (sp, sq) = (p.dot(n), q.dot(n));
        if (sp <= 0.0) == (sq <= 0.0) {
            return None;
        }
        let x = p + (q - p) * (sp / (sp - sq));
        let side = x.dot(w);
        (side > 0.0).then(|| side.atan2(x.dot(u)))
    })
}

/// `n` directions from `c` through the middle of the annulus between the loops, on
/// half-planes through the axis `u` at even angles: on each, halfway (in angle from `u`)
/// between the last point of loop a and the first of loop b. They run round `u` the way
/// loop a does.
fn meridian_ring(
    c: DVec3,
    u: DVec3,
    sign: f64,
    pa: &[DVec3],
    pb: &[DVec3],
    n: usize,
) -> Vec<DVec3> {
    use std::f64::consts::{PI, TAU};
    let e1 = u.any_orthonormal_vector();
    let e2 = u.cross(e1);
    let ka = unwrapped(pa, c, e1, e2);
    let turn = if ka[pa.len()] == ka[0] { -sign } else { (ka[pa.len()] - ka[0]).signum() };
    (0..n)
        .map(|k| {
            let phi = ka[0] + turn * TAU * (k as f64 + 0.5) / n as f64;
            let w = e1 * phi.cos() + e2 * phi.sin();
            let ta = meridian_hits(pa, c, u, w).fold(0.0, f64::max);
            let tb = meridian_hits(pb, c, u, w).fold(PI, f64::min);
            let theta = 0.5 * (ta + tb);
            u * theta.cos() + w * theta.sin()
        })
        .collect()
}

/// `n` directions from `c` at even angles in the plane normal to `w`, which separates the
/// loops (loop a on `w`'s side), running the way loop a runs round the tube: seen from `c`
/// inside an inside tube, a loop's disk turns clockwise round the axis towards it.
fn plane_ring(c: DVec3, w: DVec3, sign: f64, pa: &[DVec3], n: usize) -> Vec<DVec3> {
    use std::f64::consts::TAU;
    let e1 = w.any_orthonormal_vector();
    let e2 = w.cross(e1);
    let start = angle(pa[0] - c, e1, e2);
    (0..n)
        .map(|k| {
            let phi = start - sign * TAU * (k as f64 + 0.5) / n as f64;
            e1 * phi.cos() + e2 * phi.sin()
        })
        .collect()
}

impl Plan {
    /// The tube through `ring` (running the way loop a does): each band zipped round the
    /// first of `axes` that turns none of its triangles the wrong way, else the one that
    /// turns fewest.
    fn new(
        c: DVec3,
        sign: f64,
        pa: &[DVec3],
        pb: &[DVec3],
        ring: Vec<DVec3>,
        axes: &[DVec3],
        off: usize,
    ) -> Plan {
        let pos = |x: Vert| match x {
            Vert::A(i) => pa[i],
            Vert::B(i) => pb[i],
            Vert::Ring(i) => ring[i],
        };
        let turns_right = |t: [Vert; 3]| {
            let [p, q, r] = t.map(|x| pos(x) - c);
            p.dot(q.cross(r)) * sign > 0.0
        };
        // How far a loop vertex of the triangle can move (refinement moves it along its
        // cube edge) before the triangle turns over seen from `c`: its distance from the
        // plane through `c` and the other two vertices, least over the loop vertices.
        // Ring vertices move along their rays from `c`, which turns nothing over, but only
        // up to rounding: theirs counts in units of [`RING_CLEARANCE`], scaled to
        // [`ENOUGH`] so that one number says whether a plan clears everything it needs.
        let clearance = |t: [Vert; 3]| {
            let d = t.map(|x| pos(x) - c);
            let turn = d[0].dot(d[1].cross(d[2])) * sign;
            (0..3)
                .map(|k| {
                    let across = d[(k + 1) % 3].cross(d[(k + 2) % 3]).length();
                    let clear = if across > 0.0 { turn / across } else { 0.0 };
                    match t[k] {
                        Vert::Ring(_) => clear * (ENOUGH / RING_CLEARANCE),
                        _ => clear,
                    }
                })
                .fold(f64::INFINITY, f64::min)
        };
        let av: Vec<Vert> = (0..pa.len()).map(Vert::A).collect();
        let rv: Vec<Vert> = (0..ring.len()).map(Vert::Ring).collect();
        let bv: Vec<Vert> = (0..pb.len()).rev().map(Vert::B).collect();
        let band = |p: &[Vert], q: &[Vert]| {
            let mut best: Option<(Vec<[Vert; 3]>, usize, f64)> = None;
            for &u in axes {
                let e1 = u.any_orthonormal_vector();
                let e2 = u.cross(e1);
                let keys = |xs: &[Vert]| {
                    let ps: Vec<DVec3> = xs.iter().map(|&x| pos(x)).collect();
                    unwrapped(&ps, c, e1, e2)
                };
                let (mut kp, mut kq) = (keys(p), keys(q));
                if kp[p.len()] < kp[0] {
                    kp.iter_mut().chain(kq.iter_mut()).for_each(|k| *k = -*k);
                }
                let mut tris = Vec::with_capacity(p.len() + q.len());
                zip(p, &kp, q, &kq, &turns_right, &mut tris);
                let wrong = tris.iter().filter(|&&t| !turns_right(t)).count();
                let margin = tris.iter().map(|&t| clearance(t)).fold(f64::INFINITY, f64::min);
                if best.as_ref().is_none_or(|b| (wrong, -margin) < (b.1, -b.2)) {
                    best = Some((tris, wrong, margin));
                }
            }
            best.unwrap_or((Vec::new(), usize::MAX, f64::NEG_INFINITY))
        };
        let (mut tris, wrong_a, margin_a) = band(&av, &rv);
        let (tris_b, wrong_b, margin_b) = band(&rv, &bv);
        tris.extend(tris_b);
        // Turning the right way is not enough on the sphere of directions: the loops fix
        // the tube's cover of the annulus between them only up to whole turns round the
        // sphere, and a tube can wrap once more round `c` (every direction seen twice in the
        // annulus, once in the caps) with every triangle turning right. Its triangles' solid
        // angles then add up to more than the whole sphere; a tube that covers the annulus
        // once adds up to the annulus, less than the sphere by the loops' caps. Ring
        // vertices sliding along their rays change no triangle's solid angle.
        let seen: f64 = tris.iter().map(|t| sign * solid_angle(t.map(|x| pos(x) - c))).sum();
        let wraps = seen >= 4.0 * std::f64::consts::PI;
        let wrong = wrong_a.saturating_add(wrong_b).saturating_add(usize::from(wraps));
        Plan { centre: c, ring, tris, wrong, off, margin: margin_a.min(margin_b) }
    }

    /// What makes a plan worse: triangles turned the wrong way (a crossing is then
    /// possible), then ring vertices off the interpolant's level set.
    fn flaws(&self) -> (usize, usize, f64) {
        (self.wrong, self.off, -self.margin)
    }
}

/// The point of the interpolant's level set on the ray from `s` along `d` (a unit vector),
/// with `true`; or, where the ray has none inside the cube (it leaves through a cap) or has
/// it nearer `s` than [`MIN_RING`] (a tube pinched at a saddle on the level set), a point on
/// the ray halfway to the cube's boundary or [`MIN_RING`] from `s`, with `false`: off the
/// level set, but on the ray, which is what keeps the tube embedded.
fn ray_point(v: &[f32; 8], s: DVec3, d: DVec3) -> (DVec3, bool) {
    let exit = (0..3)
        .filter(|&i| d[i] != 0.0)
        .map(|i| if d[i] > 0.0 { (1.0 - s[i]) / d[i] } else { -s[i] / d[i] })
        .fold(f64::INFINITY, f64::min);
    // Candidates are compared with the root to about 1e-5 of the ray; the kept ring's
    // vertices are then refined on the same rays (which changes no triangle's turn).
    match level_on_ray_to(v, s.to_array(), d.to_array(), 14).map(DVec3::from_array) {
        Some(p) if p.distance(s) >= MIN_RING => (p, true),
        Some(_) => (s + d * MIN_RING.min(0.5 * exit), false),
        None => (s + d * (0.5 * exit), false),
    }
}

/// Triangles of a band between the closed sequences `p` and `q`, which run the same way
/// round the axis, with `kp`, `kq` their angle keys (`n + 1` each: the last is the first
/// after a full turn). Each triangle keeps `p`'s edges in their direction and runs `q`'s
/// backwards, as a band between a disk's boundary and the reversed boundary of another.
///
/// The walk starts from the rung between `p[0]` and the vertex of `q` nearest it in angle
/// and steps along whichever sequence's next vertex comes first round the axis, unless that
/// triangle turns the wrong way seen from the saddle and the other does not.
fn zip(
    p: &[Vert],
    kp: &[f64],
    q: &[Vert],
    kq: &[f64],
    turns_right: &dyn Fn([Vert; 3]) -> bool,
    out: &mut Vec<[Vert; 3]>,
) {
    let (np, nq) = (p.len(), q.len());
    // Rotate q to start at the vertex nearest p[0] in angle; its keys shifted within half
    // a turn of p[0]'s.
    let start = (0..nq)
        .min_by(|&x, &y| wrap(kq[x] - kp[0]).abs().total_cmp(&wrap(kq[y] - kp[0]).abs()))
        .unwrap_or(0);
    let shift = kp[0] + wrap(kq[start] - kp[0]) - kq[start];
    let key_q = |j: usize| {
        let k = start + j;
        let turns = (k / nq) as f64;
        kq[k % nq] + shift + turns * (kq[nq] - kq[0])
    };
    let pp = |i: usize| p[i % np];
    let qq = |j: usize| q[(start + j) % nq];
    let key_p = |i: usize| if i <= np { kp[i] } else { kp[np] + kp[i - np] - kp[0] };
    let (mut i, mut j) = (0, 0);
    let (mut run_p, mut run_q) = (0, 0);
    while i < np || j < nq {
        let can_p = i < np && !(i + 1 == np && j <= run_q);
        let can_q = j < nq && !(j + 1 == nq && i <= run_p);
        let tri_p = [pp(i), pp(i + 1), qq(j)];
        let tri_q = [qq(j + 1), qq(j), pp(i)];
        let advance_p = match (can_p, can_q) {
            (true, false) => true,
            (false, true) => false,
            _ => {
                let by_angle = key_p(i + 1) <= key_q(j + 1);
                let (good_p, good_q) = (turns_right(tri_p), turns_right(tri_q));
                if good_p != good_q { good_p } else { by_angle }
            }
        };
        if advance_p {
            run_p += usize::from(j == 0);
            out.push(tri_p);
            i += 1;
        } else {
            run_q += usize::from(i == 0);
            out.push(tri_q);
            j += 1;
        }
    }
}
