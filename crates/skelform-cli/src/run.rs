//! Running a scene's polygonizer with the command line's overrides: shared by the commands
//! that mesh a scene (`mesh`, `render` and `gallery`). The library chooses and runs the
//! polygonizer; this module only turns arguments into [`Overrides`].

use std::io::IsTerminal;
use std::path::Path;

use anyhow::anyhow;
use clap::Args;
use skelform::{
    DVec3, LoadOptions, Meshed, Method, Overrides, Resolution, RootMethod, Scene, Streaming,
    Threads,
};

use crate::{Failure, input, progress, runtime};

/// `--stream`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum StreamArg {
    /// Stream volumes over 256 MiB.
    Auto,
    /// Always stream.
    Always,
    /// Always hold the whole volume.
    Never,
}

impl From<StreamArg> for Streaming {
    fn from(s: StreamArg) -> Self {
        match s {
            StreamArg::Auto => Streaming::Auto,
            StreamArg::Always => Streaming::Always,
            StreamArg::Never => Streaming::Never,
        }
    }
}

/// `--method`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum MethodArg {
    /// Sample a lattice, then marching cubes with consistent topology.
    Grid,
    /// Propagate cubes from seeds across the surface (dissertation ch. 3).
    Continuation,
    /// Continuation with each cube split into six tetrahedra. Its diagonals can cut through
    /// walls or tubes thinner than a cell's diagonal that the cube method keeps; the cubes
    /// where the two join corners differently are counted and reported as a warning.
    Tetra,
    /// Marching cubes healed along self-intersections (the scene key `healing = "thesis"`
    /// gives the thesis's own per-cube healing instead of the default zone healing).
    Healed,
    /// Labelled surfaces between regions of space, meeting along curves (ch. 4).
    Nonmanifold,
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Self {
        match m {
            MethodArg::Grid => Method::Grid,
            MethodArg::Continuation => Method::Continuation,
            MethodArg::Tetra => Method::Tetra,
            MethodArg::Healed => Method::Healed,
            MethodArg::Nonmanifold => Method::NonManifold,
        }
    }
}

/// `--root`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum RootArg {
    /// Regula falsi: fewer evaluations on smooth fields (with a field that has an exact gradient, such as a skeleton or formula, a Newton step from the corners' values and gradients, about one evaluation per vertex, normals included).
    RegulaFalsi,
    /// Bisection: the dissertation's, a fixed number of halvings.
    Bisection,
    /// Continuation with an exact gradient: each vertex at the root of its edge's cubic from the corners' values and gradients, no evaluation (fewer than 3 evaluations per vertex; less accurate where a kernel ends inside an edge). Elsewhere regula falsi.
    Hermite,
}

impl From<RootArg> for RootMethod {
    fn from(r: RootArg) -> Self {
        match r {
            RootArg::RegulaFalsi => RootMethod::RegulaFalsi,
            RootArg::Bisection => RootMethod::Bisection,
            RootArg::Hermite => RootMethod::Hermite,
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
    /// Polygonizer (overrides the scene).
    #[arg(long, value_enum)]
    pub method: Option<MethodArg>,
    /// continuation/tetra: start from this point on or near the surface (repeatable;
    /// replaces the scene's seeds), e.g. --seed 0.6,0,0.
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    pub seed: Vec<[f64; 3]>,
    /// continuation/tetra: root finder (overrides the scene).
    #[arg(long, value_enum)]
    pub root: Option<RootArg>,
    /// Root-finding tolerance as a fraction of the cell (overrides the scene).
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// continuation/tetra: stop after visiting this many cubes.
    #[arg(long)]
    pub max_cells: Option<u64>,
    /// continuation/tetra: stop this many cubes from each start, in every direction.
    #[arg(long)]
    pub limit: Option<u32>,
    /// Worker threads, 1 to 256 (default: all cores). The mesh is the same for any count.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Leave out vertex normals.
    #[arg(long)]
    pub no_normals: bool,
    /// Place vertices by linear interpolation only (no root finding on the field).
    #[arg(long)]
    pub no_refine: bool,
    /// Hold no more memory than this, e.g. 512M, 4G (default 4G): what the lattice shows
    /// cannot fit is refused up front (exit 2), a run that reaches it as it goes stops (exit 1).
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

impl RunArgs {
    /// The library's overrides these arguments describe, reporting progress to `control`.
    pub fn overrides(&self) -> Result<Overrides, Failure> {
        let resolution = match (self.resolution, self.cell) {
            (Some(n), _) if n < 2 => return Err(input(anyhow!("--resolution must be at least 2"))),
            (Some(n), _) => Some(Resolution::Samples(n)),
            (None, Some(c)) if !(c.is_finite() && c > 0.0) => {
                return Err(input(anyhow!("--cell must be a positive length")));
            }
            (None, Some(c)) => Some(Resolution::Cell(c)),
            (None, None) => None,
        };
        if let Some(t) = self.tolerance
            && !(t > 0.0 && t < 1.0)
        {
            return Err(input(anyhow!("--tolerance is a fraction of the cell, between 0 and 1")));
        }
        let show_progress = !self.quiet && std::io::stderr().is_terminal();
        Ok(Overrides {
            resolution,
            method: self.method.map(Method::from),
            seeds: (!self.seed.is_empty())
                .then(|| self.seed.iter().map(|p| DVec3::from_array(*p)).collect()),
            pose: None,
            threads: self
                .threads
                .map(|n| if n == 0 { Threads::Current } else { Threads::Count(n) }),
            tolerance: self.tolerance,
            root: self.root.map(RootMethod::from),
            max_cells: self.max_cells,
            limit: self.limit,
            refine: self.no_refine.then_some(false),
            normals: self.no_normals.then_some(false),
            streaming: Some(self.stream.into()),
            max_memory: Some(memory_limit(self.max_memory, self.quiet)),
            workspace: None,
            colors: None,
            control: progress::control(show_progress),
        })
    }
}

/// A thread pool for the work the command line runs itself (drawing pictures), bounded as
/// the polygonizers bound theirs: `--threads` from 1 to 256, all cores by default.
pub fn pool(a: &RunArgs) -> Result<rayon::ThreadPool, Failure> {
    let threads = match a.threads {
        Some(n) if !(1..=skelform::MAX_THREADS).contains(&n) => {
            return Err(input(anyhow!(
                "--threads must be between 1 and {} (got {n})",
                skelform::MAX_THREADS
            )));
        }
        Some(n) => n,
        None => 0,
    };
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| runtime(anyhow!("cannot start {threads} threads: {e}")))
}

/// A library error as a command-line failure: the input's fault exits 2, the run's 1.
pub fn failure(e: skelform::Error) -> Failure {
    if e.is_input() { input(e) } else { runtime(e) }
}

/// Loads a scene, its skeleton in the named pose when one is given.
pub fn load_scene(path: &Path, pose: Option<&str>) -> Result<Scene, Failure> {
    Scene::load_with(path, &LoadOptions { pose: pose.map(str::to_string), ..Default::default() })
        .map_err(failure)
}

/// Meshes the scene as the arguments say. The mesh may be empty (see [`surface`]).
pub fn run_scene(scene: &Scene, a: &RunArgs) -> Result<Meshed, Failure> {
    let overrides = a.overrides()?;
    let result = scene.mesh(&overrides);
    progress::finish();
    result.map_err(failure)
}

/// The run's mesh, or the reason there is none; prints its warnings unless `quiet`.
pub fn surface(scene: &Scene, meshed: &Meshed, quiet: bool) -> Result<(), Failure> {
    if let Some(why) = meshed.no_surface(scene) {
        return Err(runtime(anyhow!(why)));
    }
    if !quiet {
        for w in meshed.stats.warnings() {
            errln!("warning: {w}");
        }
    }
    Ok(())
}

/// This machine's memory in bytes (Linux: `MemTotal` of /proc/meminfo), if known.
fn physical_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// `--max-memory`, held to this machine's memory: a limit above it would let a run start
/// that the system then kills, instead of refusing it with a message.
pub fn memory_limit(asked: u64, quiet: bool) -> u64 {
    match physical_memory() {
        Some(have) if asked > have => {
            if !quiet {
                errln!(
                    "warning: --max-memory {:.1} GiB is more than this machine has; the limit is its {:.1} GiB",
                    asked as f64 / (1u64 << 30) as f64,
                    have as f64 / (1u64 << 30) as f64
                );
            }
            have
        }
        _ => asked,
    }
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
