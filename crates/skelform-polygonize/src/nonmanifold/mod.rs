//! Non-manifold polygonization of multiple regions of space (dissertation ch. 4, after
//! Bloomenthal and Ferguson): space is divided into numbered regions by a
//! [`RegionField`]; the surfaces between chosen pairs of regions are polygonized together,
//! meet along curves where three regions meet, and every triangle carries its pair.
//!
//! Steps, as the chapter gives them: cubes propagate from a start across faces that hold a
//! surface of interest (or every cube of the domain is visited); each cube is split into
//! five tetrahedra, alternating with the cube's parity; every tetrahedron edge is divided
//! into `sections` pieces and each piece whose ends lie in different regions is bisected
//! `refinements` times or more, to ε, so an edge can hold several vertices; looped pairs of
//! crossings ((a,b) then (b,a) on one edge) are ignored. A face whose crossings pair off as
//! disjoint lines has no face vertex; otherwise a contour follower walks small triangles
//! along a contour to the first foreign region and puts the face vertex there. A
//! tetrahedron without face vertices of interest gives polygons of 3 or 4 sides by walking
//! from vertex to partner across its faces; one with them gets an internal vertex at their
//! mean and a triangle to each face line of interest. Triangles are wound counter-clockwise
//! seen from the lesser region of their pair. Afterwards vertices closer than
//! `close_factor · ε` along a triangle edge are merged, a vertex closer than that to the
//! opposite side of its triangle is moved onto it (the side split there; not where that
//! would fold a side round it onto its neighbour, beyond the chapter), degenerate
//! triangles dropped, and vertices duplicated per region pair so each sheet has its own
//! normal: the region function's gradient for the pair where it has one (the chapter's
//! `Gradient(p, pair)`), else the pair's area-weighted triangle normals. Beyond the chapter,
//! ties are broken by moving every point whose region is asked by one tiny generic vector
//! (see `nudge`), so lattice points on a wall never fall to the region function's tie rule.
//! [`verify`] checks a result against its region function.
//!
//! Cost (issue 18): beyond the chapter, what every segment and face vertex costs is cut to
//! what a conventional polygonizer pays, so a run evaluates the region function at most
//! about twice as often as a tetrahedral polygonizer on the same cubes
//! (`Stats::conventional_evaluations`; `bench/methods.sh` prints the ratio), where the
//! chapter's reading cost five to fifteen times. Region values at lattice points and the
//! crossings of each segment are computed once and shared by the five tetrahedra of a cube
//! and its neighbours; the changing sections of a segment are found by bisecting over the
//! section points instead of sampling all of them (the same sections wherever each region
//! is met once along the segment, see `Run::sections`); a segment whose ends lie in one
//! region is sectioned only with `Options::loops`, since without it what the chapter finds
//! there is a looped pair it drops (none was kept on any example; a wedge of two other
//! regions across such a segment, thinner than the cell, is missed); and the contour
//! follower strides in triangles four times larger before its small ones
//! (`Run::coarse_then_fine`), its first triangle's base taking its regions from the
//! samples the edge's bisection already took beside the crossing (`Run::known_region`).
//!
//! Beyond one vertex (issue 18): the chapter allows one face vertex per face and one
//! internal vertex per tetrahedron, and names more as future work. With
//! `Options::junctions` (the default), a face whose
//! unpaired crossings run to separate junctions (their contours followed to where they end)
//! gets a face vertex for each, joined by a line when a contour runs between them (two
//! junctions: the contour between the regions on either side; three or more, each holding
//! one run of consecutive crossings round the face: the sides of a polygon round the
//! region asked at their centre, or of a path along it, see `linked_runs`). With four
//! crossings the region the first contour meets says which two junctions there can be, so
//! two contours are followed, not all four. A sheet crossing a face as such a line between
//! two face vertices (a slab's end thinner than the cell) can have no edge vertex of its
//! pair in the tetrahedra on either side to be wound by: its triangles are wound like their
//! neighbours across shared sides, and where none reaches them by where the line's two
//! regions touch the face's sides (`Run::orient`). Always (it costs no
//! evaluations), a face vertex of four regions becomes two, at the two junctions where
//! their contours were followed to them (else ε either side of the followed end), joined
//! by the short contour between them, where that contour is a
//! cap (drawn, with a drawn sheet beside it at each end: a vein's slab reaching the leaf's
//! margin, whose two sides one vertex folded onto each other; see
//! `Run::four_region_split`). Always, a tetrahedron's contours are split into the
//! components they make on its surface, a
//! component without face vertices is polygonized on its own, and a curve passing through
//! (two face vertices where the same regions meet) gets its own internal vertex: one
//! vertex at the mean of every face vertex folded the sheets of a curve clipping a corner
//! of the tetrahedron (see `Run::tetrahedron`); where the fan to the mean of a
//! component's other face vertices still folds (a slab's corner at the margin a hair from
//! a face vertex, its other curves leaving a cell away), their meeting point is taken at
//! the face vertex nearest the others that folds nothing. Always, where a
//! curve runs straight into a tetrahedron and straight out at an angle, its internal vertex
//! is moved to where the two lines meet, so the corner is kept instead of bevelled
//! (`Stats::sharpened_corners`).
//!
//! Guarantees: deterministic output on any thread count; every triangle labelled with a
//! pair of interest; intersection curves output as labelled polylines. Not guaranteed:
//! junctions closer than a sixteenth of a cell on one face share a face vertex, and
//! junctions on one face that do not each hold one run of consecutive crossings (or whose
//! centre lies in a region of their own crossings) share one, so features finer than a
//! cell can still be lost; a corner is kept only where the
//! curve is straight for two face vertices on each side; looped intersections are cut off
//! unless `Options::loops` (beyond the chapter) keeps them, and one entering and leaving
//! within one section of an edge is never seen.

pub mod tets;
pub mod verify;

mod edges;
mod faces;
mod post;
mod propagation;
mod tetrahedra;

use std::time::{Duration, Instant};

use glam::DVec3;
use rustc_hash::{FxHashMap, FxHashSet};
use skelform_field::RegionField;
use skelform_field::grid::Grid;
use skelform_mesh::{CurveEdge, Mesh, RegionPair, RegionTriple};

use crate::lattice::cubes::{CubeLattice, Key};
use crate::lattice::memory;
use crate::lattice::search::CoarseSearch;
use crate::{Error, LatticeOptions, Resolution};
use edges::Crossing;
use faces::FaceInfo;

/// Settings of the non-manifold polygonizer.
#[derive(Clone, Debug)]
pub struct Options {
    /// The lattice, progress, threads and memory limit. Vertices are placed by bisection on
    /// the region function to `epsilon`, so `refine`, `tolerance` and `normals` are not read
    /// (normals always come out). Storage grows with the surfaces: its running account is
    /// held to `max_memory` as propagation goes ([`Error::MemoryLimit`]); full-grid mode,
    /// whose cube list and caches are known from the lattice, is refused up front when they
    /// cannot fit ([`Error::TooMuchMemory`]).
    pub lattice: LatticeOptions,
    /// Start points within about half a cell of a surface of interest; with none, the
    /// domain is searched every `search_stride` cells.
    pub seeds: Vec<DVec3>,
    /// Stride of the domain search, in cells: regions thinner than that can be missed.
    pub search_stride: usize,
    /// Visit every cube of the domain instead of propagating from starts.
    pub full_grid: bool,
    /// The surfaces to polygonize; empty means every pair that occurs.
    pub interest: Vec<RegionPair>,
    /// The intersection curves to output (the chapter's curves of interest); empty means
    /// every curve of the surfaces of interest.
    pub curves: Vec<RegionTriple>,
    /// Edge sections (the chapter's n = 16).
    pub sections: u32,
    /// Least bisections per section (the chapter's m = 4).
    pub refinements: u32,
    /// Accuracy of edge and face vertices; `None`: cell / 256.
    pub epsilon: Option<f64>,
    /// Vertices closer than `close_factor · ε` along a triangle edge are merged.
    pub close_factor: f64,
    /// Beyond the chapter: keep looped crossings ((a,b) then (b,a) on one edge, a surface
    /// poking through the edge) instead of ignoring them; in each face around the edge the
    /// contour between them is followed and a vertex put where it is farthest from the
    /// edge, so the poke is made rather than cut off. Off: the chapter's truncation.
    pub loops: bool,
    /// Stop propagating after visiting this many cubes (then `Stats::reached_budget`).
    pub max_cells: u64,
    /// Beyond the chapter: a face vertex per junction of a face (the module's "Beyond one
    /// vertex"; an internal vertex per curve and per contour component of a tetrahedron is
    /// made either way). On by default: following the contours of faces with four or more
    /// crossings costs about 1.5% more evaluations on the leaves (1.95 times a conventional
    /// polygonizer's on the three-lobed leaf; 1.98 without it before the follower's first
    /// triangle reused the edge's samples). Off: the chapter's one face vertex per face,
    /// which fuses junctions on one face into one vertex.
    pub junctions: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            lattice: LatticeOptions {
                resolution: Resolution::Cell(1.0 / 32.0),
                ..LatticeOptions::default()
            },
            seeds: Vec::new(),
            search_stride: 4,
            full_grid: false,
            interest: Vec::new(),
            curves: Vec::new(),
            sections: 16,
            refinements: 4,
            epsilon: None,
            close_factor: 1.0,
            loops: false,
            max_cells: 5_000_000,
            junctions: true,
        }
    }
}

/// What a run did.
#[derive(Clone, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct Stats {
    /// Side of the cubes (each split into five tetrahedra), in the region function's units.
    pub cell: f64,
    /// Accuracy to which edge and face vertices are placed (the chapter's ε).
    pub epsilon: f64,
    /// Evaluations of the region function: the run's cost, compared in
    /// `conventional_evaluations`.
    pub region_evaluations: u64,
    /// What a conventional (manifold) tetrahedral polygonizer would evaluate on the same
    /// cells: the corners, and eight bisection steps on each edge whose ends differ (the
    /// chapter's comparison: it reports about four times fewer than its method; this one
    /// evaluates at most about twice as many, see the module's "Cost").
    pub conventional_evaluations: u64,
    /// Cubes visited (by propagation from the starts, or every cube in full-grid mode).
    pub cells_visited: u64,
    /// Vertices on tetrahedron edges, where the region changes along the edge.
    pub edge_vertices: usize,
    /// Vertices inside tetrahedron faces, where three or more regions meet on the face.
    pub face_vertices: usize,
    /// Vertices inside tetrahedra, where the region contours of its faces meet.
    pub internal_vertices: usize,
    /// Face vertices the contour follower could not reach (placed at the mean of the
    /// face's crossings instead).
    pub face_vertex_fallbacks: usize,
    /// Face vertices put on an edge crossing because a third region lies within 2ε of it
    /// along its edge (the follower's first triangle would already hold it).
    pub face_vertices_at_crossing: usize,
    /// Looped crossings ((a,b) then (b,a) on one edge: a surface poking through) left out, as
    /// the chapter does. Only those met on segments whose ends differ are counted: without
    /// `Options::loops` a segment whose ends share a region is not sectioned at all.
    pub looped_pairs_ignored: usize,
    /// Looped pairs kept (`Options::loops`), and their face vertices placed by following
    /// the contour (the rest by a fallback half a crossing gap into the face).
    pub looped_pairs_kept: usize,
    /// Face vertices placed for kept looped pairs.
    pub loop_vertices: usize,
    /// Of those, the ones placed half a crossing gap into the face because the contour could
    /// not be followed.
    pub loop_vertex_fallbacks: usize,
    /// Vertices merged into a neighbour closer than `close_factor · ε` along a triangle edge
    /// (post-processing).
    pub merged_vertices: usize,
    /// Internal vertices of curves moved to the curve's corner (see the module's
    /// "Beyond one vertex" paragraph).
    pub sharpened_corners: usize,
    /// Vertices of thin triangles moved onto the midpoint of the opposite side.
    pub snapped_to_edges: usize,
    /// Triangles removed by post-processing because merging or snapping collapsed them.
    pub dropped_triangles: usize,
    /// Vertex normals taken from the region function's per-pair gradient (the rest are
    /// area-weighted triangle normals).
    pub gradient_normals: usize,
    /// Triangles whose side regions could not be told apart by a probe (kept as wound).
    pub unoriented_triangles: usize,
    #[cfg_attr(
        feature = "serde",
        serde(rename = "surfaces", serialize_with = "crate::summary::surfaces")
    )]
    /// Triangles of each surface, by region pair, in pair order.
    pub triangles_per_pair: Vec<(RegionPair, usize)>,
    #[cfg_attr(
        feature = "serde",
        serde(rename = "curves", serialize_with = "crate::summary::curves")
    )]
    /// Length of each intersection curve, by the three regions meeting there.
    pub curve_length_per_triple: Vec<(RegionTriple, f64)>,
    /// Whether a surface reached the domain box (the mesh is open there).
    pub reached_domain: bool,
    /// Whether propagation ran out of cells (`max_cells`) with surface left to visit.
    pub reached_budget: bool,
    /// Vertices in the mesh (copies per region pair included).
    pub vertices: usize,
    /// Triangles in the mesh.
    pub triangles: usize,
    /// Wall time of the whole run.
    #[cfg_attr(feature = "serde", serde(serialize_with = "crate::summary::seconds"))]
    pub time: Duration,
}

/// The crossings bisected on one segment, in order: (parameter along it, region before,
/// region after).
type Bisected = Vec<(f64, u32, u32)>;

struct Run<'a> {
    regions: &'a dyn RegionField,
    grid: Grid,
    cubes: CubeLattice,
    opts: &'a Options,
    eps: f64,
    /// Added to every point whose region is asked (see [`nudge`]).
    nudge: DVec3,
    interest: Option<FxHashSet<RegionPair>>,
    point_region: FxHashMap<Key, u32>,
    edges: FxHashMap<(Key, Key), Vec<Crossing>>,
    /// Every crossing bisected on a segment (looped ones included), as (parameter along
    /// lo → hi, region before, region after): what the segment's samples say about the
    /// regions along it ([`Run::known_region`]).
    samples: FxHashMap<(Key, Key), Bisected>,
    /// Lines between two face vertices (a contour joining two junctions of a face), keyed
    /// by their vertices (lesser first): a direction across the line within the face, the
    /// region it points into, and the line's pair. The sheet's triangles on such a line
    /// have no edge vertex of their pair to be wound by ([`Run::orient`]).
    link_sides: FxHashMap<(u32, u32), (DVec3, u32, RegionPair)>,
    faces: FxHashMap<[Key; 3], FaceInfo>,
    /// Sides on tetrahedron faces of the triangles made so far round face vertices, with
    /// the third corner of each: where a tetrahedron's fan would fold onto its
    /// neighbour's across a face ([`Run::folded_since`]).
    fan_sides: FxHashMap<[u32; 2], Vec<u32>>,
    positions: Vec<DVec3>,
    /// The lattice segment of each edge vertex.
    on_edge: FxHashMap<u32, (Key, Key)>,
    /// For edge vertices: the segment's direction and the regions before and after the
    /// crossing along it, which say on which side of the surface each region lies.
    crossing: Vec<Option<(DVec3, u32, u32)>>,
    triangles: Vec<[u32; 3]>,
    labels: Vec<RegionPair>,
    /// Internal vertices of curves passing through a tetrahedron: the vertex, the face
    /// vertices where the curve enters and leaves, and the tetrahedron (for sharpening).
    through: Vec<(u32, [u32; 2], [Key; 4])>,
    /// Face vertices of five or more regions and the internal vertices they join, merged
    /// into one point by post-processing.
    fused: Vec<(u32, u32)>,
    curves: Vec<CurveEdge>,
    visited: FxHashSet<Key>,
    /// Bytes held by the vectors inside `edges` and `faces` entries (charged as they are
    /// made): the rest of the account is read off lengths and capacities ([`Run::held`]).
    inner_bytes: u64,
    stats: Stats,
}

/// Polygonizes the surfaces of interest between the regions of `regions`.
///
/// ```
/// use skelform_field::{Aabb, DVec3, region::FnRegions};
/// use skelform_mesh::RegionPair;
/// use skelform_polygonize::{LatticeOptions, Resolution};
/// use skelform_polygonize::nonmanifold::{polygonize, Options};
/// // A ball (1) cut by the plane z = 0 into an upper (2) and lower (3) half-space.
/// let regions = FnRegions(|p: DVec3| if p.length() < 0.5 { 1 } else if p.z > 0.0 { 2 } else { 3 });
/// let lattice = LatticeOptions { domain: Aabb::cube(1.0), resolution: Resolution::Cell(0.1), ..Default::default() };
/// let opts = Options { lattice, full_grid: true, ..Options::default() };
/// let (mesh, stats) = polygonize(&regions, &opts).unwrap();
/// let pairs: Vec<RegionPair> = stats.triangles_per_pair.iter().map(|(p, _)| *p).collect();
/// assert_eq!(pairs, vec![RegionPair(1, 2), RegionPair(1, 3), RegionPair(2, 3)]);
/// assert!(!mesh.curves.is_empty());
/// ```
pub fn polygonize(regions: &dyn RegionField, options: &Options) -> Result<(Mesh, Stats), Error> {
    options.lattice.threads.install(|| polygonize_here(regions, options))
}

/// [`polygonize`] on the current thread pool.
fn polygonize_here(regions: &dyn RegionField, options: &Options) -> Result<(Mesh, Stats), Error> {
    let started = Instant::now();
    let grid = options.lattice.grid()?;
    if options.sections == 0 || options.close_factor.is_nan() || options.close_factor < 0.0 {
        return Err(Error::BadOption(
            "sections must be at least 1 and close_factor not negative".into(),
        ));
    }
    if let Some(ids) = regions.region_ids() {
        for t in &options.curves {
            if let Some(r) = t.0.iter().find(|r| !ids.contains(r)) {
                return Err(Error::BadOption(format!(
                    "the curve {t} names region {r}, which the region function does not have (it has {ids:?})"
                )));
            }
        }
        for p in &options.interest {
            for r in [p.0, p.1] {
                if !ids.contains(&r) {
                    return Err(Error::BadOption(format!(
                        "the pair {}_{} names region {r}, which the region function does not have (it has {ids:?})",
                        p.0, p.1
                    )));
                }
            }
        }
    }
    let eps = options.epsilon.unwrap_or(grid.cell / 256.0);
    let mut run = Run {
        regions,
        grid,
        cubes: CubeLattice::new(grid),
        opts: options,
        eps,
        nudge: nudge(eps),
        interest: (!options.interest.is_empty())
            .then(|| options.interest.iter().copied().collect()),
        point_region: FxHashMap::default(),
        edges: FxHashMap::default(),
        samples: FxHashMap::default(),
        link_sides: FxHashMap::default(),
        faces: FxHashMap::default(),
        fan_sides: FxHashMap::default(),
        positions: Vec::new(),
        on_edge: FxHashMap::default(),
        crossing: Vec::new(),
        triangles: Vec::new(),
        labels: Vec::new(),
        through: Vec::new(),
        fused: Vec::new(),
        curves: Vec::new(),
        visited: FxHashSet::default(),
        inner_bytes: 0,
        stats: Stats { cell: grid.cell, epsilon: eps, ..Stats::default() },
    };
    let max_memory = options.lattice.max_memory;
    memory::refuse(memory_need(&grid, options), max_memory, &grid)?;
    let starts = if options.full_grid { run.all_cubes() } else { run.starts()? };
    run.propagate(starts)?;
    run.sharpen();
    run.orient();
    let mesh = run.finish();
    let mut stats = run.stats;
    stats.time = started.elapsed();
    Ok((mesh, stats))
}

/// The perturbation that breaks ties: every point whose region the run asks for is moved by
/// this fixed vector, `ε / 1024` long, in the direction `(1, √2 − 1, 1 − √3)`, which no plane
/// through lattice points with small integer normals contains.
///
/// Walls that pass exactly through lattice points (a sheet on a lattice plane, the
/// bisecting planes of a symmetric foam on a lattice centred on its symmetry) would
/// otherwise leave those points to the region function's rounding or its tie rule: a point
/// on the wall between regions 1 and 2 of ordered regions belongs to neither (its fields
/// are zero, not negative) and falls to the default region, and a sheet's side flips from
/// point to point with the rounding of its distance. That made coincident, oppositely
/// wound triangles and saw-toothed borders whose face vertices fell back to the mean of the
/// crossings. Moved by the same vector, every point lies strictly on one side of such a
/// wall, decided the same way wherever it is asked (corners, sections, bisection, contour
/// following), as if the lattice were offset by an infinitesimal generic amount; the
/// geometric error, `ε / 1024`, is far below the ε to which vertices are placed. (Which way
/// is arbitrary; with `z` negative a sheet on a lattice plane has its lattice points on its
/// lower side, and the tee's fillets meet it without folds, which the other way gives
/// at the foot of each fillet.)
fn nudge(eps: f64) -> DVec3 {
    let d = DVec3::new(1.0, std::f64::consts::SQRT_2 - 1.0, 1.0 - 3f64.sqrt());
    d.normalize() * (eps / 1024.0)
}

/// What a run with `options` on `grid` holds before it finds the surface: the full grid's
/// cubes and caches in full-grid mode, else the coarse search (its points and a region
/// each) when no seed is given; then what grows with the surface.
pub fn memory_need(grid: &Grid, options: &Options) -> crate::MemoryNeed {
    if options.full_grid {
        crate::MemoryNeed::FullGrid(full_grid_need(grid).unwrap_or(u64::MAX))
    } else if options.seeds.is_empty() {
        crate::MemoryNeed::Search(CoarseSearch::need(grid, options.search_stride, 4))
    } else {
        crate::MemoryNeed::Surface
    }
}

/// What full-grid mode holds at the least, from the lattice alone (`None` when it does not
/// even fit in a `u64`): the list of every cube (twice: the starts and the wave made of
/// them), the set of visited cubes, the region at every lattice point, and the cached faces
/// and segments (each cube brings at least its three lower square faces, cut in two, its
/// four inner tetrahedron faces, and the three edges and three face diagonals at its lowest
/// corner). Tables are counted full to the brim and the crossings and mesh not at all.
fn full_grid_need(grid: &Grid) -> Option<u64> {
    let cubes = grid.dims.iter().try_fold(1u64, |n, &d| n.checked_mul(d as u64 - 1))?;
    let points = grid.dims.iter().try_fold(1u64, |n, &d| n.checked_mul(d as u64))?;
    let list = cubes.checked_mul(2 * size_of::<[u32; 3]>() as u64)?;
    let visited = memory::entries_bytes::<Key, ()>(cubes)?;
    let regions = memory::entries_bytes::<Key, u32>(points)?;
    let faces = memory::entries_bytes::<[Key; 3], FaceInfo>(cubes.checked_mul(10)?)?;
    let edges = memory::entries_bytes::<(Key, Key), Vec<Crossing>>(cubes.checked_mul(6)?)?;
    [visited, regions, faces, edges].into_iter().try_fold(list, u64::checked_add)
}

/// What every step shares: keys of lattice points and region evaluation, counted.
impl Run<'_> {
    /// Bytes held: the caches, the vertices, triangles and curves, and what
    /// post-processing will add for each vertex and triangle (merging, the copies per
    /// region pair, normals, and the mesh's own arrays).
    fn held(&self) -> u64 {
        use memory::{map_bytes, set_bytes, vec_bytes};
        // Per vertex: the union-find parent, its entry in the merged sums, the merged
        // positions, a copy per pair with its map entry, its accumulated normal, and the
        // mesh's position and normal; per triangle: the kept triangle with its pair, and
        // the mesh's triangle and label.
        let per_vertex = (size_of::<u32>()
            + 2 * size_of::<(u32, (DVec3, f64))>()
            + size_of::<DVec3>()
            + 2 * size_of::<((u32, RegionPair), u32)>()
            + size_of::<(DVec3, RegionPair)>()
            + size_of::<DVec3>()
            + 2 * size_of::<[f32; 3]>()) as u64;
        let per_triangle = (size_of::<([u32; 3], RegionPair)>()
            + size_of::<[u32; 3]>()
            + size_of::<RegionPair>()) as u64;
        map_bytes(&self.point_region)
            + map_bytes(&self.edges)
            + map_bytes(&self.samples)
            + map_bytes(&self.link_sides)
            + map_bytes(&self.faces)
            + map_bytes(&self.fan_sides)
            + self.inner_bytes
            + vec_bytes(&self.positions)
            + map_bytes(&self.on_edge)
            + vec_bytes(&self.crossing)
            + vec_bytes(&self.triangles)
            + vec_bytes(&self.labels)
            + vec_bytes(&self.through)
            + vec_bytes(&self.fused)
            + vec_bytes(&self.curves)
            + set_bytes(&self.visited)
            + self.positions.len() as u64 * per_vertex
            + self.triangles.len() as u64 * per_triangle
    }

    fn key(&self, p: [u32; 3]) -> Key {
        self.cubes.key(p)
    }

    fn unkey(&self, k: Key) -> [u32; 3] {
        self.cubes.unkey(k)
    }

    fn point(&self, k: Key) -> DVec3 {
        self.cubes.point(self.unkey(k))
    }

    fn interesting(&self, pair: RegionPair) -> bool {
        pair.0 != pair.1 && self.interest.as_ref().is_none_or(|s| s.contains(&pair))
    }

    fn regions_of(&mut self, pts: &[DVec3]) -> Vec<u32> {
        let mut out = vec![0; pts.len()];
        let moved: Vec<DVec3> = pts.iter().map(|&p| p + self.nudge).collect();
        self.regions.region_many(&moved, &mut out);
        self.stats.region_evaluations += pts.len() as u64;
        out
    }

    fn region_at(&mut self, p: DVec3) -> u32 {
        self.stats.region_evaluations += 1;
        self.regions.region(p + self.nudge)
    }
}
