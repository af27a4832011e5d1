//! Scene files: what to polygonize, where, how finely, and how to write it.
//!
//! A scene is TOML. Every key is checked: an unknown key, a value of the wrong type, a
//! formula that does not parse, each is an error that names the file, line and column, and
//! says what was expected. Nothing is silently ignored.
//!
//! ```
//! let text = r#"
//! [domain]
//! min = [-1, -1, -1]
//! max = [1, 1, 1]
//! [mesh]
//! resolution = 32
//! [field]
//! parameters = { R = 0.5 }
//! formula = """
//! r = sqrt(x^2 + y^2 + z^2)
//! r - R
//! """
//! "#;
//! let scene = skelform_scene::Scene::parse(text, "sphere.toml").unwrap();
//! assert_eq!(scene.domain.max.x, 1.0);
//! ```
//!
//! The format is documented with examples in `docs/SCENES.md`.
#![warn(missing_docs)]

mod diag;
mod leaf;
mod patch_blend;
mod pose;
mod ramiform;
mod regions;
mod schema;
mod skeleton;
mod sweep;
#[cfg(test)]
mod testing;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use skelform_field::formula::Formula;
use skelform_field::{Aabb, Field, Iso};
use skelform_mesh::io::Format;
use skelform_polygonize::grid::Resolution;

pub use leaf::LeafRegions;
pub use pose::{Articulation, REST as REST_POSE};
pub use regions::Regions;
pub use schema::{Method, ParseMethodError};
pub use skelform_field::combine::Combine;
pub use sweep::FILE_KEYS;

/// A picture of a scene in the gallery beside its default one (`[scene] views`).
#[derive(Clone, Debug, PartialEq)]
pub struct GalleryView {
    /// Names the picture: `hand.toml` with view `back` is drawn as `…-hand-back.png`.
    pub name: String,
    /// Where the camera looks from, in degrees, as `skelform render --view`: the azimuth …
    pub azimuth: f64,
    /// … and the elevation (from -90 to 90).
    pub elevation: f64,
    /// The pose to draw it in (default: the scene's).
    pub pose: Option<String>,
}

/// A loaded, validated scene.
#[derive(Clone)]
pub struct Scene {
    /// Where it came from (for messages); `"<string>"` when parsed from text.
    pub origin: String,
    /// `[scene] name`: a title for the gallery and `skelform info`, in place of the file
    /// name.
    pub name: Option<String>,
    /// `[scene] description`: a sentence on what the scene shows, printed by `skelform info`.
    pub description: Option<String>,
    /// The dissertation figure the scene reproduces (`figure = "3.12"` in `[scene]`), shown
    /// beside its picture in the gallery.
    pub figure: Option<String>,
    /// `[scene] views`: more pictures of the scene for the gallery, each from its own view
    /// and in its own pose.
    pub views: Vec<GalleryView>,
    /// `[scene] turntable`: the gallery also draws the scene turning once about z, in this
    /// many frames (an animated PNG).
    pub turntable: Option<u32>,
    /// `[domain]`: the box the polygonizer may visit; a surface that leaves it is cut open
    /// there.
    pub domain: Aabb,
    /// How finely to mesh: `[mesh] resolution` (samples along the domain's longest side) or
    /// `cell` (a cell size), never both; 128 samples when the file gives neither.
    pub resolution: Resolution,
    /// `[mesh] method`, the polygonizer the scene is meant for (the command line's
    /// `--method` overrides it); [`Method::Grid`] when absent.
    pub method: Method,
    /// `[mesh] refine` (default true): move vertices onto the surface by root finding on
    /// the field; false keeps the linear interpolation along lattice edges, which is faster
    /// and shows what refinement buys.
    pub refine: bool,
    /// Root-finding tolerance as a fraction of the cell.
    pub tolerance: f64,
    /// Settings of the continuation and tetra methods.
    pub continuation: Continuation,
    /// Settings of the healed method.
    pub healed: Healed,
    /// Regions of space for the non-manifold method, when the scene has `[regions]`.
    pub regions: Option<Regions>,
    /// The leaf of chapter 7 as regions (beyond, vein, above, below), when the scene has
    /// `[leaf]`; meshed by the non-manifold method like `[regions]`.
    pub leaf: Option<LeafRegions>,
    /// True when the scene has `[regions]` (or `[leaf]`) and neither a formula nor a skeleton: only the
    /// non-manifold method can mesh it.
    pub regions_only: bool,
    /// The field with the iso value already subtracted: its zero set is the surface.
    pub field: Arc<dyn Field>,
    /// The skeletal field when the scene has a `[skeleton]` (already in `field`, alone or
    /// combined with the formula), for statistics and seeds.
    pub skeleton: Option<Arc<skelform_skeleton::SkeletonField>>,
    /// The skeleton's field with its sweeps, when `[skeleton]` has `[[skeleton.sweep]]`s:
    /// what gives mesh vertices their texture coordinates
    /// ([`SweptField::uv`](skelform_skeleton::SweptField::uv)).
    pub sweeps: Option<Arc<skelform_skeleton::SweptField>>,
    /// The compiled formula (before the iso value), for `skelform info`; the constant `1`
    /// when the scene has a skeleton and no `[field]`.
    pub formula: Arc<Formula>,
    /// The level the surface is taken at: `[field] iso` (default 0), or the skeleton's own
    /// when there is no formula. Already subtracted in `field`; kept for `skelform info`.
    pub iso: f64,
    /// What `[output]` asks for (file, format, text or binary, normals).
    pub output: Output,
    /// Joints and poses, when the skeleton has them: the pose the field was built in and
    /// the others a load could ask for ([`LoadOptions::pose`]).
    pub articulation: Option<Articulation>,
}

/// Choices a load makes that the file leaves open (the command line's).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadOptions {
    /// Build the skeleton in this pose instead of the scene's `pose` (or `rest`); a name the
    /// scene does not define is an error listing the ones it does.
    pub pose: Option<String>,
    /// Turn the skeleton part of the way from that pose towards another (animation, DIS
    /// §2.8): each joint's rotation is interpolated, never the elements' positions, so limbs
    /// keep their lengths.
    pub toward: Option<PoseBlend>,
    /// The folder that relative paths in the file (a sweep's `section_image`) are taken
    /// from: the scene file's folder. `None`: the current folder ([`Scene::load_with`]
    /// fills it in from the file's path when it is `None`).
    pub base: Option<PathBuf>,
}

/// Part of the way towards another pose: [`LoadOptions::toward`].
#[derive(Clone, Debug, PartialEq)]
pub struct PoseBlend {
    /// The pose turned towards.
    pub pose: String,
    /// How far, from 0 (the first pose) to 1 (this one).
    pub t: f64,
}

impl std::fmt::Debug for Scene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scene")
            .field("origin", &self.origin)
            .field("name", &self.name)
            .field("domain", &self.domain)
            .field("resolution", &self.resolution)
            .field("method", &self.method)
            .field("iso", &self.iso)
            .finish_non_exhaustive()
    }
}

/// Settings that only the continuation polygonizer reads.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Continuation {
    /// Where propagation starts: `[mesh] seeds` (each checked to be inside the domain) or,
    /// when the file gives none, a point on each skeleton element or on the leaf. Empty: the
    /// polygonizer searches the domain for the surface.
    pub seeds: Vec<skelform_field::DVec3>,
    /// `[mesh] root`: how an edge's crossing is found, regula falsi (the default,
    /// superlinear on smooth fields) or bisection (the dissertation's, one bit of position
    /// per evaluation whatever the field).
    pub root: skelform_polygonize::refine::RootMethod,
    /// `[mesh] max_cells`: the most cubes to visit before stopping (the mesh is then open
    /// where propagation stopped); `None` takes the polygonizer's budget. The non-manifold
    /// method reads it too, and `--max-cells` overrides it.
    pub max_cells: Option<u64>,
    /// `[mesh] limit`: how many cubes propagation may go from each component's first cube,
    /// for surfaces that are unbounded within the domain; `None` for no limit.
    pub limit: Option<u32>,
    /// `[mesh] search_stride`: the stride, in cells, of the coarse search for the surface
    /// when there are no seeds (larger is faster but may miss small parts); `None` takes the
    /// polygonizer's. The non-manifold method reads it too.
    pub search_stride: Option<usize>,
}

/// Settings that only the healed polygonizer reads (`[mesh]` keys `epsilon`,
/// `critical_cells`, `split_sheets`, `healing`).
#[derive(Clone, Debug, PartialEq)]
pub struct Healed {
    /// The thesis's absolute critical test, `|f_x| + |f_y| + |f_z| < epsilon` (with
    /// `healing = "thesis"` the default, at the thesis's 0.2).
    pub epsilon: Option<f64>,
    /// The scale-free critical test in cells (the zone healing's default when neither is
    /// given).
    pub critical_cells: Option<f64>,
    /// One copy of each self-intersection vertex per sheet, with that sheet's normal (the
    /// default, so that renders have no seam along the crossings); `false` shares the curve
    /// vertices between the sheets.
    pub split_sheets: bool,
    /// Which healing: the zone healing (default) or the thesis's own per-cube patterns
    /// (`healing = "thesis"`, which reproduces its triangle counts).
    pub healing: skelform_polygonize::healed::Healing,
}

impl Default for Healed {
    /// Per-sheet curve vertices and the zone healing, as the healed polygonizer's own
    /// defaults.
    fn default() -> Self {
        Self {
            epsilon: None,
            critical_cells: None,
            split_sheets: true,
            healing: skelform_polygonize::healed::Healing::Zone,
        }
    }
}

/// Output settings a scene may state; the command line overrides them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Output {
    /// Default output file, relative to the scene file's folder.
    pub file: Option<PathBuf>,
    /// `[output] format`: when the scene's own `file` is used, its extension must name this
    /// format (a mismatch is an error rather than a file in the wrong format); `None` lets
    /// the extension decide.
    pub format: Option<Format>,
    /// `[output] ascii`: PLY as text instead of binary (as `--ascii` does).
    pub ascii: bool,
    /// `[output] normals` (default true): write per-vertex normals where the format keeps
    /// them; `--no-normals` turns them off whatever the scene says.
    pub normals: bool,
}

/// A scene that cannot be used, with where and why.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file, as it was given.
        path: String,
        /// Why the system could not read it.
        #[source]
        source: std::io::Error,
    },
    /// Anything wrong inside the file: syntax, unknown key, bad value, bad formula.
    #[error("{path}:{line}:{column}: {message}")]
    At {
        /// The file, as it was given (`<string>` for text parsed directly).
        path: String,
        /// 1-based line of the offending value.
        line: usize,
        /// 1-based column, counted in characters as editors count them.
        column: usize,
        /// What is wrong and what was expected, without the position.
        message: String,
    },
    /// The scene cannot be used as asked, with no one place in the file to blame: a pose
    /// the command line asks for that the scene does not define, or a posed skeleton that
    /// cannot be built.
    #[error("{path}: {message}")]
    Invalid {
        /// The file, as it was given.
        path: String,
        /// What is wrong.
        message: String,
    },
}

/// What the non-manifold polygonizer needs from a scene's `[regions]` or `[leaf]`.
pub struct NonManifoldSetup {
    /// The region function: the scene's region formulas in order (with the default region
    /// or the patch blend behind them), or the leaf's blade and veins.
    pub field: Arc<dyn skelform_field::RegionField>,
    /// Surfaces of interest (region pairs).
    pub interest: Vec<skelform_mesh::RegionPair>,
    /// Curves of interest (region triples); empty: every curve between surfaces of interest.
    pub curves: Vec<skelform_mesh::RegionTriple>,
    /// `full_grid`: visit every cube of the domain instead of propagating from seeds;
    /// slower, but it finds surfaces that no seed leads to.
    pub full_grid: bool,
    /// Resolve looped intersections (beyond the chapter).
    pub loops: bool,
}

impl Scene {
    /// What the non-manifold method polygonizes: the region function, the pairs of interest
    /// and whether to visit every cube; from `[leaf]` or `[regions]`.
    pub fn nonmanifold_regions(&self) -> Option<NonManifoldSetup> {
        if let Some(l) = &self.leaf {
            return Some(NonManifoldSetup {
                field: l.region_field(),
                interest: l.interest.clone(),
                curves: Vec::new(),
                full_grid: l.full_grid,
                loops: false,
            });
        }
        self.regions.as_ref().map(|r| NonManifoldSetup {
            field: r.field.clone() as Arc<dyn skelform_field::RegionField>,
            interest: r.interest.clone(),
            curves: r.curves.clone(),
            full_grid: r.full_grid,
            loops: r.loops,
        })
    }

    /// Reads and validates a scene file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        Scene::load_with(path, &LoadOptions::default())
    }

    /// Reads and validates a scene file with choices from outside it (a pose).
    pub fn load_with(path: &Path, options: &LoadOptions) -> Result<Scene, SceneError> {
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|source| SceneError::Io { path: shown.clone(), source })?;
        let mut options = options.clone();
        if options.base.is_none() {
            options.base = path.parent().map(Path::to_path_buf);
        }
        let mut scene = Scene::parse_with(&text, &shown, &options)?;
        if let (Some(file), Some(dir)) = (&scene.output.file, path.parent()) {
            scene.output.file = Some(dir.join(file));
        }
        Ok(scene)
    }

    /// Validates scene text; `origin` names it in messages.
    pub fn parse(text: &str, origin: &str) -> Result<Scene, SceneError> {
        schema::build(text, origin, &LoadOptions::default())
    }

    /// Validates scene text with choices from outside it (a pose).
    pub fn parse_with(
        text: &str,
        origin: &str,
        options: &LoadOptions,
    ) -> Result<Scene, SceneError> {
        schema::build(text, origin, options)
    }
}

pub(crate) fn iso_field(formula: Arc<Formula>, iso: f64) -> Arc<dyn Field> {
    if iso == 0.0 { formula } else { Arc::new(Iso { field: formula, iso }) }
}
