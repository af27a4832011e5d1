//! [`Live`]: meshing a scene again and again as it is edited, redoing only what an edit
//! changed.

use std::sync::Arc;
use std::time::Instant;

use skelform_polygonize::Resolution;
use skelform_polygonize::incremental::{self, GridState, Reuse};
use skelform_skeleton::SkeletonField;

use crate::meshing::Plan;
use crate::{Error, Meshed, Overrides, Scene, Stats};

/// Meshes successive versions of a scene (an editor's), re-meshing only where an edit
/// changed the field; every mesh is the one [`Scene::mesh`] makes, bit for bit.
///
/// It keeps the last run's lattice samples, vertices and normals. When the next scene's
/// skeleton differs from the last one's only in some elements (moved, radius or strength
/// changed, a joint turned, which moves every element after it, an element added or
/// removed), it samples again only within the old and new reach of those elements (boxes
/// from [`SkeletonField::changes_since`]), places again only the vertices on lattice edges
/// within a cell of them (and takes the others' colours from the last run), and runs the
/// extraction again over the slabs of held samples there
/// ([`skelform_polygonize::incremental`]). Anything else
/// runs from scratch: another method than the grid, another lattice (domain, resolution),
/// root finding or normals setting, a scene whose field is not its skeleton alone (a
/// formula combined with it), or a change that every point depends on (blend, iso value,
/// blend groups, junctions; [`skelform_skeleton::GlobalChange`]). [`Live::last_run`] says
/// which happened and why.
///
/// ```
/// let text = std::fs::read_to_string("../../examples/skeleton/hand.toml")?;
/// let scene = skelform::Scene::parse(&text, "hand.toml")?;
/// let coarse = skelform::Overrides {
///     resolution: Some(skelform::Resolution::Samples(48)),
///     ..Default::default()
/// };
/// let mut live = skelform::Live::new();
/// live.mesh(&scene, &coarse)?;
/// // An edit: the index finger's second knuckle bent by 10 degrees more.
/// let knuckle = "name = \"index2\"\nparent = \"index1\"\nat = [0.75, 0, 0]\naxes = [\"y\"]\nangles = 30";
/// let bent = text.replacen(knuckle, &knuckle.replace("angles = 30", "angles = 40"), 1);
/// let bent = skelform::Scene::parse(&bent, "hand.toml")?;
/// let meshed = live.mesh(&bent, &coarse)?;
/// let run = live.last_run().unwrap();
/// assert!(run.incremental && run.reuse.reused_vertices > run.reuse.placed_vertices);
/// assert_eq!(meshed.mesh, bent.mesh(&coarse)?.mesh); // the fresh run's mesh, bit for bit
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Default)]
pub struct Live {
    last: Option<Last>,
    run: Option<LiveRun>,
}

/// What the last grid run left for the next.
struct Last {
    skeleton: Arc<SkeletonField>,
    state: GridState,
    /// The vertex colours it painted, by vertex (empty without colours).
    colors: Vec<[f32; 3]>,
}

/// How [`Live`]'s last run went.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LiveRun {
    /// Whether it re-meshed only the changed part.
    pub incremental: bool,
    /// Why it ran from scratch, when it did.
    pub full_because: Option<String>,
    /// What it sampled again and what it reused (a full run reuses nothing).
    pub reuse: Reuse,
}

impl Live {
    /// Nothing kept yet: the first run is a full one.
    pub fn new() -> Live {
        Live::default()
    }

    /// How the last run went: incremental or not, and why.
    pub fn last_run(&self) -> Option<&LiveRun> {
        self.run.as_ref()
    }

    /// Drops what the last run kept (the sampled lattice: memory), so the next run is a
    /// full one.
    pub fn forget(&mut self) {
        self.last = None;
    }

    /// Meshes `scene` with `overrides`: the mesh [`Scene::mesh`] makes, bit for bit,
    /// re-meshing only what changed since the last call where it can (see [`Live`]). A
    /// failed run forgets what was kept (the next is a full one); a cancelled incremental
    /// run keeps it, with the boxes it had started to re-sample, for the next to redo.
    pub fn mesh(&mut self, scene: &Scene, overrides: &Overrides) -> Result<Meshed, Error> {
        if let Some(pose) = &overrides.pose {
            let posed = scene.posed(pose)?;
            let plain = Overrides { pose: None, ..overrides.clone() };
            return self.mesh(&posed, &plain);
        }
        let last = self.last.take();
        let result = self.mesh_here(scene, overrides, last);
        if result.as_ref().is_err_and(|e| !e.is_cancelled()) {
            self.last = None;
        }
        result
    }

    fn mesh_here(
        &mut self,
        scene: &Scene,
        o: &Overrides,
        last: Option<Last>,
    ) -> Result<Meshed, Error> {
        let full = |live: &mut Live, why: &str| {
            live.run = Some(LiveRun { full_because: Some(why.to_string()), ..LiveRun::default() });
        };
        let (method, plan) = scene.plan(o)?;
        let Plan::Grid(options) = plan else {
            full(self, "only the grid method re-meshes incrementally");
            return scene.mesh(o);
        };
        // Only a field that is the skeleton alone can be compared element by element.
        let skeleton = match &scene.skeleton {
            Some(sk) if std::ptr::addr_eq(Arc::as_ptr(sk), Arc::as_ptr(&scene.field)) => sk.clone(),
            _ => {
                full(self, "the scene's field is not a skeleton alone");
                return scene.mesh(o);
            }
        };
        let polygonize_error = |source| Error::Polygonize { origin: scene.origin.clone(), source };
        let started = Instant::now();
        let changes = match &last {
            None => Err("nothing kept from a last run".to_string()),
            Some(l) if !l.state.matches(&options) => {
                Err("the lattice, root finding or normals changed".to_string())
            }
            Some(l) => skeleton.changes_since(&l.skeleton).map_err(|g| g.to_string()),
        };
        // The colours of the last run, when an edit left them valid where it did not reach.
        let mut old_colors = Vec::new();
        let (mut mesh, stats, state, run) = match (changes, last) {
            (Ok(boxes), Some(mut l)) => {
                let (mesh, stats, reuse) =
                    match l.state.update(scene.field.as_ref(), &options, &boxes) {
                        Ok(done) => done,
                        Err(e) => {
                            if matches!(e, skelform_polygonize::Error::Cancelled) {
                                // Still the last finished run's skeleton outside the
                                // boxes the state now holds as pending.
                                self.last = Some(l);
                            }
                            return Err(polygonize_error(e));
                        }
                    };
                let run = LiveRun { incremental: !reuse.full, full_because: None, reuse };
                // Colours are per element and not among the changes: an edit that
                // recoloured, added or removed an element paints every vertex again.
                if !reuse.full && l.skeleton.element_colors() == skeleton.element_colors() {
                    old_colors = std::mem::take(&mut l.colors);
                }
                (mesh, stats, l.state, run)
            }
            (why, _) => {
                let why = why.err().unwrap_or_default();
                match incremental::polygonize(scene.field.as_ref(), &options) {
                    Ok((mesh, stats, state)) => {
                        let reuse = Reuse {
                            resampled: stats.samples,
                            placed_vertices: mesh.vertex_count(),
                            full: true,
                            ..Reuse::default()
                        };
                        let run = LiveRun { incremental: false, full_because: Some(why), reuse };
                        (mesh, stats, state, run)
                    }
                    // Too large to hold: the plain run may still stream it.
                    Err(skelform_polygonize::Error::TooMuchMemory { .. }) => {
                        full(self, "the lattice is too large to keep");
                        return scene.mesh(o);
                    }
                    Err(e) => return Err(polygonize_error(e)),
                }
            }
        };
        // A vertex taken from the last run is at the same place, on a lattice edge that misses
        // every changed element's old and new box: its colour is the same, bit for bit (those
        // elements are skipped there, before as after: the same reason its position is
        // unchanged). Found by its number, not its position: no map of every vertex.
        let painted = Instant::now();
        scene.paint_with(&mut mesh, method, o, |i, _| {
            if old_colors.is_empty() {
                return None;
            }
            state.previous_vertex(i).and_then(|o| old_colors.get(o).copied())
        });
        let painting = painted.elapsed();
        let colors = mesh.colors.clone();
        self.last = Some(Last { skeleton, state, colors });
        self.run = Some(run);
        let elapsed = started.elapsed();
        Ok(Meshed { mesh, stats: Stats::Grid(stats), method, elapsed, painting })
    }

    /// Progressive results (DIS §3.7: refinement during idle time): meshes `scene` at
    /// `levels` resolutions, each twice as fine as the one before and the last the one
    /// `overrides` asks for, calling `each(level, &meshed)` with each mesh as it is made
    /// (level 0 the coarsest); returns the last. Coarse levels whose lattice would have fewer
    /// than 8 samples along its longest side are left out. The last level goes through
    /// [`Live::mesh`] (incremental where it can be) and is [`Scene::mesh`]'s mesh, bit for
    /// bit. A cancellation through `overrides.control` (a new edit) stops it between levels
    /// or within one, with an error for which [`Error::is_cancelled`] holds.
    pub fn mesh_progressive(
        &mut self,
        scene: &Scene,
        overrides: &Overrides,
        levels: usize,
        mut each: impl FnMut(usize, &Meshed),
    ) -> Result<Meshed, Error> {
        let cancelled = || Error::Polygonize {
            origin: scene.origin.clone(),
            source: skelform_polygonize::Error::Cancelled,
        };
        let posed;
        let (scene, overrides) = match &overrides.pose {
            Some(pose) => {
                posed = (scene.posed(pose)?, Overrides { pose: None, ..overrides.clone() });
                (&posed.0, &posed.1)
            }
            None => (scene, overrides),
        };
        let finest = scene.lattice(overrides)?;
        let mut level = 0;
        for k in (1..levels).rev() {
            if overrides.control.is_cancelled() {
                return Err(cancelled());
            }
            let cell = finest.cell * f64::from(1u32 << k.min(20));
            let coarse =
                Overrides { resolution: Some(Resolution::Cell(cell)), ..overrides.clone() };
            match scene.lattice(&coarse) {
                Ok(l) if l.dims.iter().max().is_some_and(|&d| d >= 8) => {}
                _ => continue,
            }
            let meshed = scene.mesh(&coarse)?;
            each(level, &meshed);
            level += 1;
        }
        if overrides.control.is_cancelled() {
            return Err(cancelled());
        }
        let meshed = self.mesh(scene, overrides)?;
        each(level, &meshed);
        Ok(meshed)
    }
}
