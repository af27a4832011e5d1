//! Issue 18, defect 4: the chapter's own limits (one face vertex per face, one internal
//! vertex per tetrahedron) made spurious short curves where several regions meet at a point
//! and bevelled the corners of curves. These scenes have exact curves to compare with.

use std::collections::{BTreeMap, BTreeSet};

use glam::DVec3;
use skelform_field::region::FnRegions;
use skelform_field::{Aabb, RegionField};
use skelform_mesh::{Mesh, RegionTriple};
use skelform_polygonize::nonmanifold::{Options, Stats, polygonize};
use skelform_polygonize::{LatticeOptions, Resolution};

fn lattice(domain: Aabb, cell: f64) -> LatticeOptions {
    LatticeOptions { domain, resolution: Resolution::Cell(cell), ..Default::default() }
}

/// One connected polyline of a curve label: its vertices' positions and its length.
#[derive(Debug)]
struct Polyline {
    label: RegionTriple,
    points: Vec<DVec3>,
    length: f64,
}

/// The mesh's curves split into connected polylines per label (vertices identified by
/// position: they are duplicated per pair).
fn polylines(m: &Mesh) -> Vec<Polyline> {
    let key = |i: u32| m.positions[i as usize].map(f32::to_bits);
    let pos = |i: u32| DVec3::from_array(m.positions[i as usize].map(f64::from));
    let mut by_label: BTreeMap<RegionTriple, Vec<(u32, u32)>> = BTreeMap::new();
    for c in &m.curves {
        by_label.entry(c.label).or_default().push((c.v[0], c.v[1]));
    }
    let mut out = Vec::new();
    for (label, segs) in by_label {
        // Union-find over position keys.
        let mut id: BTreeMap<[u32; 3], usize> = BTreeMap::new();
        let mut point: Vec<DVec3> = Vec::new();
        let mut idx = |v: u32| {
            let n = id.len();
            *id.entry(key(v)).or_insert_with(|| {
                point.push(pos(v));
                n
            })
        };
        let segs: Vec<(usize, usize, f64)> =
            segs.iter().map(|&(a, b)| (idx(a), idx(b), pos(a).distance(pos(b)))).collect();
        let mut parent: Vec<usize> = (0..point.len()).collect();
        fn root(p: &mut [usize], mut x: usize) -> usize {
            while p[x] != x {
                p[x] = p[p[x]];
                x = p[x];
            }
            x
        }
        for &(a, b, _) in &segs {
            let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
            parent[ra.max(rb)] = ra.min(rb);
        }
        let mut comps: BTreeMap<usize, (BTreeSet<usize>, f64)> = BTreeMap::new();
        for &(a, b, l) in &segs {
            let r = root(&mut parent, a);
            let e = comps.entry(r).or_default();
            e.0.extend([a, b]);
            e.1 += l;
        }
        for (_, (pts, length)) in comps {
            out.push(Polyline { label, points: pts.iter().map(|&i| point[i]).collect(), length });
        }
    }
    out
}

/// Four regions, each the points nearest one of four centres at the vertices of a regular
/// tetrahedron around `o`: six flat walls meeting in fours curves (rays from `o` away
/// from each centre... each ray where three cells meet) at the single point `o`.
fn plateau(o: DVec3) -> impl RegionField {
    let c = [
        DVec3::new(1.0, 1.0, 1.0),
        DVec3::new(1.0, -1.0, -1.0),
        DVec3::new(-1.0, 1.0, -1.0),
        DVec3::new(-1.0, -1.0, 1.0),
    ];
    FnRegions(move |p: DVec3| {
        let d = c.map(|c| (p - o - c).length_squared());
        (0..4).min_by(|&i, &j| d[i].total_cmp(&d[j])).unwrap_or(0) as u32
    })
}

/// The eight octants around `o`: regions by the signs of `p - o` (bit 0 x, 1 y, 2 z).
fn octants(o: DVec3) -> impl RegionField {
    FnRegions(move |p: DVec3| {
        let d = p - o;
        u32::from(d.x > 0.0) | u32::from(d.y > 0.0) << 1 | u32::from(d.z > 0.0) << 2
    })
}

/// A box `|x|, |y|, |z| < h` around `o` (regions 2 above the plane `z = o.z + zc`, 3 below),
/// in region 0: the plane's square border is a curve (0, 2, 3) with four right-angle corners.
fn cut_box(o: DVec3, h: f64, zc: f64) -> impl RegionField {
    FnRegions(move |p: DVec3| {
        let d = p - o;
        if d.x.abs().max(d.y.abs()).max(d.z.abs()) > h {
            0
        } else if d.z > zc {
            2
        } else {
            3
        }
    })
}

fn run(regions: &dyn RegionField, cell: f64) -> (Mesh, Stats) {
    let opts = Options {
        lattice: lattice(Aabb::cube(1.0), cell),
        full_grid: true,
        junctions: true,
        ..Options::default()
    };
    polygonize(regions, &opts).unwrap()
}

/// The junction of the scenes, off the lattice's symmetry.
const O: DVec3 = DVec3::new(0.0123, -0.0217, 0.0311);

fn print(name: &str, s: &Stats, lines: &[Polyline]) {
    let lengths: Vec<([u32; 3], f64)> =
        lines.iter().map(|l| (l.label.0, (l.length * 1000.0).round() / 1000.0)).collect();
    eprintln!(
        "{name} cell {}: {} polylines {lengths:?}; {} face, {} internal vertices, {} corners \
         sharpened, {:.2}x a conventional polygonizer's evaluations",
        s.cell,
        lines.len(),
        s.face_vertices,
        s.internal_vertices,
        s.sharpened_corners,
        s.region_evaluations as f64 / s.conventional_evaluations as f64
    );
}

/// With `Options::junctions`. Four cells of a foam meeting at a point: four curves (rays from the point, each where
/// three cells meet, with its own label) and nothing else. Two of the rays can leave a
/// tetrahedron through one face, which then holds two junctions.
#[test]
fn four_cells_meeting_at_a_point_give_four_whole_curves() {
    for cell in [0.1, 0.08, 0.06, 0.04] {
        let (m, s) = run(&plateau(O), cell);
        let lines = polylines(&m);
        print("plateau", &s, &lines);
        let labels: BTreeSet<RegionTriple> = lines.iter().map(|l| l.label).collect();
        assert_eq!((lines.len(), labels.len()), (4, 4), "cell {cell}");
        for l in &lines {
            // Each ray runs from the junction to the domain's box, about √3 away.
            assert!(l.length > 1.5, "cell {cell}: {:?} only {} long", l.label, l.length);
            let near = l.points.iter().map(|p| p.distance(O)).fold(f64::MAX, f64::min);
            assert!(near < 0.5 * cell, "cell {cell}: {:?} ends {near} from the junction", l.label);
        }
        assert!(s.region_evaluations <= 2 * s.conventional_evaluations);
    }
}

/// With `Options::junctions`. Three planes through one point: eight octants, and six curves (the half-axes, each where
/// four octants meet) from the point. One face vertex per face fused the two junctions of a
/// face that two half-axes cross, and left a spurious piece of curve, 0.02 to 0.04 long, with
/// a label of three octants that meet nowhere along a curve, at every cell tried. With a face
/// vertex per junction it was gone at 0.08 and 0.04, but at 0.1 and 0.06 one such piece
/// remained, where all three planes cross a face near the point: three junctions on one face,
/// now joined as a triangle of contours round the octant they enclose.
#[test]
fn three_planes_through_a_point_give_six_curves_and_no_short_pieces() {
    for cell in [0.1, 0.08, 0.06, 0.04] {
        let (m, s) = run(&octants(O), cell);
        let lines = polylines(&m);
        print("octants", &s, &lines);
        let short: Vec<&Polyline> = lines.iter().filter(|l| l.length < cell).collect();
        assert!(short.is_empty(), "cell {cell}: short curves {short:?}");
        assert_eq!(lines.len(), 6, "cell {cell}: one curve per half-axis");
        assert!(s.region_evaluations <= 2 * s.conventional_evaluations);
    }
}

/// The corners of a curve: a plane cut off by a box has a square border whose corners the
/// chapter's midpoint of two face vertices bevels (by up to a quarter cell along the
/// diagonal). Sharpened corners lie on the square, and the mesh's curve comes closer to the
/// true corners than before.
#[test]
fn a_square_border_keeps_its_corners() {
    let (mut sharpened, mut close) = (0, 0);
    for cell in [0.1, 0.08, 0.06, 0.04] {
        let (m, s) = run(&cut_box(O, 0.5, 0.0), cell);
        let lines = polylines(&m);
        print("box", &s, &lines);
        assert_eq!(lines.len(), 1);
        sharpened += s.sharpened_corners;
        // Every curve vertex on the square's border: within the follower's accuracy away
        // from the corners, within half a cell (a bevel) at one that is not sharpened.
        let off = |p: &DVec3| {
            let d = *p - O;
            ((d.x.abs().max(d.y.abs()) - 0.5).abs()).max(d.z.abs())
        };
        let by_corner = |p: &&DVec3| {
            let d = **p - O;
            d.x.abs().min(d.y.abs()) > 0.5 - cell
        };
        let worst = lines[0].points.iter().filter(|p| !by_corner(p)).map(off).fold(0.0, f64::max);
        assert!(worst < 8.0 * s.epsilon, "cell {cell}: a curve vertex {worst} off the border");
        let worst = lines[0].points.iter().map(off).fold(0.0, f64::max);
        assert!(worst < 0.5 * cell, "cell {cell}: a corner's vertex {worst} off the border");
        let mut nearest = Vec::new();
        for (sx, sy) in [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)] {
            let corner = O + DVec3::new(sx * 0.5, sy * 0.5, 0.0);
            let d = lines[0].points.iter().map(|p| p.distance(corner)).fold(f64::MAX, f64::min);
            nearest.push(d / cell);
            close += usize::from(d < 0.1 * cell);
        }
        eprintln!("  nearest curve vertex to each corner, in cells: {nearest:.3?}");
    }
    assert!(sharpened >= 4 && close >= 4, "{sharpened} sharpened, {close} corners within 0.1 cell");
}

/// A vein's slab reaching a leaf's margin: region 1 between `|z - h| < t` (2 above, 3
/// below), cut off by 0 beyond the curved margin. Where the slab is thinner than the
/// lattice resolves, its end (the sheet (0, 1)) crosses faces between two junctions, (0, 1,
/// 2) and (0, 1, 3), with no edge vertex of its own pair.
fn slab_end(h: f64, t: f64) -> impl RegionField {
    FnRegions(move |p: DVec3| {
        if p.y > 0.36 + 0.07 * p.x + 0.1 * p.x * p.x {
            0
        } else if (p.z - h).abs() < t {
            1
        } else if p.z > h {
            2
        } else {
            3
        }
    })
}

/// With `Options::junctions`. A slab's end thinner than a cell crosses faces as a line
/// between two face vertices: its triangles had no edge vertex of their pair to be wound
/// by, and none of their neighbours had either, so they kept the winding they were made
/// with (18 inconsistent edges at `t` = 0.02 cell, as on the leaves: 41 and 45). They are
/// wound by which region lies on which side of the line in the face.
#[test]
fn a_slab_ending_between_two_junctions_is_wound_like_its_neighbours() {
    let cell = 0.1;
    for (h, t) in [(0.0137, 0.002), (0.0431, 0.002), (0.0137, 0.003), (-0.0291, 0.0025)] {
        let (mesh, stats) = run(&slab_end(h, t), cell);
        let pairs: Vec<[u32; 2]> =
            stats.triangles_per_pair.iter().map(|p| [p.0.0, p.0.1]).collect();
        assert!(pairs.contains(&[0, 1]), "h {h}, t {t}: the slab's end is drawn: {pairs:?}");
        assert_eq!(stats.unoriented_triangles, 0, "h {h}, t {t}");
        let report = skelform_mesh::check::check(&mesh);
        assert_eq!(report.inconsistent_edges, 0, "h {h}, t {t}");
        assert_eq!(report.folded_edges, 0, "h {h}, t {t}");
        assert_eq!(report.coincident_faces, 0, "h {h}, t {t}");
        assert_eq!(report.duplicate_faces, 0, "h {h}, t {t}");
    }
}
