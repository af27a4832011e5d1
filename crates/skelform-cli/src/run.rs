//! Running a scene's polygonizer with the command line's overrides: shared by the commands
//! that mesh a scene (`mesh`, and `render` when given a scene).

use std::io::IsTerminal;

use anyhow::anyhow;
use clap::Args;
use skelform_field::DVec3;
use skelform_mesh::Mesh;
use skelform_polygonize::grid::{self, Resolution};
use skelform_polygonize::{LatticeOptions, Threads};
use skelform_polygonize::{continuation, healed, nonmanifold, refine::RootMethod};
use skelform_scene::{Method, Scene};

use crate::{Failure, input, progress, report, runtime};

/// `--stream`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum StreamArg {
    Auto,
    Always,
    Never,
}

impl From<StreamArg> for grid::Streaming {
    fn from(s: StreamArg) -> Self {
        match s {
            StreamArg::Auto => grid::Streaming::Auto,
            StreamArg::Always => grid::Streaming::Always,
            StreamArg::Never => grid::Streaming::Never,
        }
    }
}

/// How to polygonize a scene; every option overrides the scene's own setting.
#[derive(Args, Clone, Debug)]
pub struct RunArgs {
    /// Samples along the domain's longest side (overrides the scene).
    #[arg(long, conflicts_with = "cell")]
    pub resolution: Option<usize>,
    /// Cell size (overrides the scene).
    #[arg(long)]
    pub cell: Option<f64>,
    /// Polygonizer (overrides the scene): grid, continuation, tetra or healed.
    #[arg(long)]
    pub method: Option<String>,
    /// continuation/tetra: start from this point on or near the surface (repeatable;
    /// replaces the scene's seeds), e.g. --seed 0.6,0,0.
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    pub seed: Vec<[f64; 3]>,
    /// continuation/tetra: root finder, regula-falsi or bisection (overrides the scene).
    #[arg(long)]
    pub root: Option<String>,
    /// Root-finding tolerance as a fraction of the cell (overrides the scene).
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// continuation/tetra: stop after visiting this many cubes.
    #[arg(long)]
    pub max_cells: Option<u64>,
    /// continuation/tetra: stop this many cubes from each start, in every direction.
    #[arg(long)]
    pub limit: Option<u32>,
    /// Worker threads (default: all cores). The mesh is the same for any count.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Leave out vertex normals.
    #[arg(long)]
    pub no_normals: bool,
    /// Place vertices by linear interpolation only (no root finding on the field).
    #[arg(long)]
    pub no_refine: bool,
    /// Refuse grids that would need more memory than this, e.g. 512M, 4G (default 4G).
    #[arg(long, value_parser = parse_bytes, default_value = "4G")]
    pub max_memory: u64,
    /// grid: sample the volume slab by slab as it is extracted instead of holding it whole
    /// (auto: for volumes over 256 MiB). The mesh is the same either way.
    #[arg(long, value_enum, default_value_t = StreamArg::Auto)]
    pub stream: StreamArg,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
    /// Build an articulated skeleton in this named pose (overrides the scene's `pose`);
    /// `rest` is every joint at its default angles.
    #[arg(long)]
    pub pose: Option<String>,
}

/// Start points: the command line's `--seed`s, else the scene's seeds.
fn seeds(scene: &Scene, a: &RunArgs) -> Vec<DVec3> {
    if a.seed.is_empty() {
        scene.continuation.seeds.clone()
    } else {
        a.seed.iter().map(|p| DVec3::from_array(*p)).collect()
    }
}

/// Polygonizes the scene as the arguments say; returns the mesh, the run's statistics and
/// the method used.
pub fn run_scene(scene: &Scene, a: &RunArgs) -> Result<(Mesh, report::Run, Method), Failure> {
    let method = match &a.method {
        Some(m) => m.parse::<Method>().map_err(input)?,
        None => scene.method,
    };
    let resolution = match (a.resolution, a.cell) {
        (Some(n), _) if n < 2 => return Err(input(anyhow!("--resolution must be at least 2"))),
        (Some(n), _) => Resolution::Samples(n),
        (None, Some(c)) if !(c.is_finite() && c > 0.0) => {
            return Err(input(anyhow!("--cell must be a positive length")));
        }
        (None, Some(c)) => Resolution::Cell(c),
        (None, None) => scene.resolution,
    };
    // No count (or 0): the caller's pool, by default a thread per core.
    let threads = match a.threads {
        None | Some(0) => Threads::Current,
        Some(n) => Threads::Count(n),
    };

    let show_progress = !a.quiet && std::io::stderr().is_terminal();
    let control = progress::control(show_progress);
    let refine = scene.refine && !a.no_refine;
    let tolerance = match a.tolerance {
        Some(t) if !(t > 0.0 && t < 1.0) => {
            return Err(input(anyhow!("--tolerance is a fraction of the cell, between 0 and 1")));
        }
        Some(t) => t,
        None => scene.tolerance,
    };
    let normals = scene.output.normals && !a.no_normals;
    let field = scene.field.as_ref();
    if scene.regions_only && method != Method::NonManifold {
        return Err(input(anyhow!(
            "{}: the scene has [regions] and no [field]: mesh it with method = \"nonmanifold\"",
            scene.origin
        )));
    }
    let lattice = LatticeOptions {
        domain: scene.domain,
        resolution,
        refine,
        tolerance,
        normals,
        max_memory: a.max_memory,
        control,
        threads,
    };
    let result = match method {
        Method::Grid => {
            let options = grid::Options { lattice, streaming: a.stream.into(), workspace: None };
            grid::polygonize(field, &options).map(|(m, s)| (m, report::Run::Grid(s)))
        }
        Method::NonManifold => {
            let Some(setup) = scene.nonmanifold_regions() else {
                return Err(input(anyhow!(
                    "{}: --method nonmanifold needs [regions] or [leaf] in the scene",
                    scene.origin
                )));
            };
            let defaults = nonmanifold::Options::default();
            let options = nonmanifold::Options {
                lattice,
                seeds: seeds(scene, a),
                search_stride: scene.continuation.search_stride.unwrap_or(defaults.search_stride),
                full_grid: setup.full_grid,
                loops: setup.loops,
                interest: setup.interest,
                curves: setup.curves,
                max_cells: a
                    .max_cells
                    .or(scene.continuation.max_cells)
                    .unwrap_or(defaults.max_cells),
                ..defaults
            };
            nonmanifold::polygonize(setup.field.as_ref(), &options)
                .map(|(m, s)| (m, report::Run::NonManifold(Box::new(s))))
        }
        Method::Continuation | Method::Tetra => {
            let c = &scene.continuation;
            let defaults = continuation::Options::default();
            let root = match a.root.as_deref() {
                None => c.root,
                Some("regula-falsi") => RootMethod::RegulaFalsi,
                Some("bisection") => RootMethod::Bisection,
                Some(other) => {
                    return Err(input(anyhow!(
                        "unknown root finder '{other}'; expected regula-falsi or bisection"
                    )));
                }
            };
            let options = continuation::Options {
                lattice,
                seeds: seeds(scene, a),
                search_stride: c.search_stride.unwrap_or(defaults.search_stride),
                cells: if method == Method::Tetra {
                    continuation::Cells::Tetrahedra
                } else {
                    continuation::Cells::Cubes
                },
                root,
                max_cells: a.max_cells.or(c.max_cells).unwrap_or(defaults.max_cells),
                limit: a.limit.or(c.limit),
            };
            continuation::polygonize(field, &options)
                .map(|(m, s)| (m, report::Run::Continuation(s)))
        }
        Method::Healed => {
            let h = &scene.healed;
            let options = healed::Options {
                lattice,
                epsilon: match (h.epsilon, h.critical_cells) {
                    (Some(e), _) => healed::Epsilon::Absolute(e),
                    (None, Some(c)) => healed::Epsilon::Cells(c),
                    (None, None) => healed::Options::default().epsilon,
                },
                split_sheets: h.split_sheets,
                ..healed::Options::default()
            };
            healed::polygonize(field, &options).map(|(m, s)| (m, report::Run::Healed(Box::new(s))))
        }
    };
    progress::finish();
    let (mesh, stats) = result.map_err(|e| {
        use skelform_polygonize::Error as E;
        match e {
            E::TooMuchMemory { .. } | E::Grid(_) | E::BadSeed { .. } | E::BadOption(_) => {
                input(anyhow!("{}: {e}", scene.origin))
            }
            E::NoSurfaceFound { .. } => runtime(anyhow!("{}: {e}", scene.origin)),
            e => runtime(e),
        }
    })?;
    Ok((mesh, stats, method))
}

pub fn parse_bytes(s: &str) -> Result<u64, String> {
    let s = s.trim();
    let (num, mult) = match s.char_indices().find(|(_, c)| c.is_ascii_alphabetic()) {
        Some((i, _)) => {
            let unit = s[i..].to_ascii_uppercase();
            let m = match unit.trim_end_matches("IB").trim_end_matches('B') {
                "" => 1u64,
                "K" => 1 << 10,
                "M" => 1 << 20,
                "G" => 1 << 30,
                "T" => 1 << 40,
                _ => return Err(format!("unknown unit '{}' (use K, M, G or T)", &s[i..])),
            };
            (&s[..i], m)
        }
        None => (s, 1),
    };
    let n: f64 = num.trim().parse().map_err(|_| format!("'{s}' is not a size like 512M or 4G"))?;
    if !(n.is_finite() && n > 0.0) {
        return Err(format!("'{s}' must be a positive size"));
    }
    Ok((n * mult as f64) as u64)
}

pub fn parse_point(s: &str) -> Result<[f64; 3], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let nums: Vec<f64> = parts.iter().filter_map(|p| p.parse().ok()).collect();
    match <[f64; 3]>::try_from(nums) {
        Ok(p) if parts.len() == 3 && p.iter().all(|x| x.is_finite()) => Ok(p),
        _ => Err(format!("'{s}' is not a point like 0.5,0,-1")),
    }
}
