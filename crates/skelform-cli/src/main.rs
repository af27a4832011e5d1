//! `skelform`: polygonize implicit-surface scenes and check meshes.
//!
//! A thin layer over the library crates: it parses arguments, loads the scene, runs a
//! polygonizer, writes the mesh and prints statistics. Exit codes: 0 success, 1 runtime
//! failure (nothing to mesh, cannot write), 2 bad input or usage.

#[macro_use]
mod console;
mod animate;
mod extract;
mod gallery;
mod progress;
mod render;
mod report;
mod run;
mod studio;

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::anyhow;
use clap::{Args, Parser, Subcommand};
use skelform::mesh::io::{Format, PlyCurves, WriteOptions, read_mesh, write_mesh};

#[derive(Parser)]
#[command(name = "skelform", version, about = "Implicit surfaces, skeletal forms and their meshes")]
#[command(
    after_help = "Exit codes: 0 success, 1 runtime failure, 2 bad input or usage, 3 defects found by `check --strict`."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Polygonize a scene (grid, continuation, tetra, healed or nonmanifold method) and write
    /// the mesh (PLY, OBJ, STL or glTF binary, by the output's extension).
    Mesh(MeshArgs),
    /// Report a mesh's topology: edges, components, genus, orientation, defects.
    Check(CheckArgs),
    /// Show what a scene describes: domain, grid, memory needed, the compiled formula.
    Info(InfoArgs),
    /// Marching cubes on a raw float32 volume (extraction only, no field).
    Extract(extract::ExtractArgs),
    /// Draw a scene (meshed first) or a mesh file as a PNG picture.
    Render(render::RenderArgs),
    /// Turn an articulated scene from one pose to another: an animated PNG, or a mesh per
    /// frame (DIS §2.8).
    Animate(animate::AnimateArgs),
    /// Render every example scene into docs/gallery, with a page of figures and statistics.
    Gallery(gallery::GalleryArgs),
    /// Edit a scene in the browser and watch its surface: a local web page with the skeleton,
    /// its handles and parameters; saving writes the TOML back with its comments.
    Studio(studio::StudioArgs),
    /// Print a shell completion script, e.g. `skelform completions bash >
    /// ~/.local/share/bash-completion/completions/skelform`.
    Completions {
        /// The shell to complete in.
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
}

#[derive(Args)]
struct MeshArgs {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Output mesh; the extension picks the format (.ply, .obj, .stl, .glb); `-` writes to
    /// standard output (with --format). Defaults to the scene's [output] file.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// The output format when the path does not say (`-o -`), or to override its extension.
    #[arg(long, value_enum)]
    format: Option<FormatArg>,
    #[command(flatten)]
    run: run::RunArgs,
    /// Print statistics: samples, evaluations, vertices, triangles, time per phase.
    #[arg(long)]
    stats: bool,
    /// Print statistics as JSON on standard output.
    #[arg(long)]
    json: bool,
    /// Write PLY as text instead of binary.
    #[arg(long)]
    ascii: bool,
    /// Where a PLY file's curves go: `separate`, in OUT.curves.ply beside it (the mesh file
    /// then has only vertices and faces, which trimesh, meshio and pymeshlab read); `inline`,
    /// as an `edge` element in the mesh file (one file, read by skelform); `none`.
    #[arg(long, value_enum, default_value_t = PlyCurvesArg::Separate, value_name = "WHERE")]
    ply_curves: PlyCurvesArg,
    /// Leave the curves out of the file, whatever the format (glTF line primitives, which
    /// pymeshlab cannot read; OBJ `l` lines; PLY curves).
    #[arg(long)]
    no_curves: bool,
}

/// `--format`: a mesh file format.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum FormatArg {
    Ply,
    Obj,
    Stl,
    Glb,
}

impl From<FormatArg> for Format {
    fn from(a: FormatArg) -> Self {
        match a {
            FormatArg::Ply => Format::Ply,
            FormatArg::Obj => Format::Obj,
            FormatArg::Stl => Format::Stl,
            FormatArg::Glb => Format::Glb,
        }
    }
}

/// Whether a path argument means a standard stream.
fn is_stdio(path: &Path) -> bool {
    path.as_os_str() == "-"
}

/// The format of a mesh read from a stream, from its first bytes: glTF and PLY say so,
/// binary STL has a size that its triangle count fixes, ASCII STL starts with `solid` and
/// has facets; anything else is taken as OBJ.
fn sniff(bytes: &[u8]) -> Format {
    let stl_binary = bytes.len() >= 84 && {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        n.checked_mul(50).and_then(|b| b.checked_add(84)) == Some(bytes.len() as u64)
    };
    let head = &bytes[..bytes.len().min(512)];
    if bytes.starts_with(b"glTF") {
        Format::Glb
    } else if bytes.starts_with(b"ply") {
        Format::Ply
    } else if stl_binary || (bytes.starts_with(b"solid") && head.windows(5).any(|w| w == b"facet"))
    {
        Format::Stl
    } else {
        Format::Obj
    }
}

/// `--ply-curves`: [`PlyCurves`] for the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum PlyCurvesArg {
    Separate,
    Inline,
    None,
}

impl From<PlyCurvesArg> for PlyCurves {
    fn from(a: PlyCurvesArg) -> Self {
        match a {
            PlyCurvesArg::Separate => PlyCurves::Separate,
            PlyCurvesArg::Inline => PlyCurves::Inline,
            PlyCurvesArg::None => PlyCurves::None,
        }
    }
}

#[derive(Args)]
struct CheckArgs {
    /// The mesh (PLY ascii or binary, OBJ, STL, glTF binary); `-` reads standard input (the
    /// format from --format, else from the first bytes).
    mesh: PathBuf,
    /// The format of the input, when its name does not say (`-`) or says wrong.
    #[arg(long, value_enum)]
    format: Option<FormatArg>,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    /// Exit with status 3 when the mesh is not a clean closed manifold (open, non-manifold,
    /// inconsistently oriented, invalid, duplicate or coincident faces, folded edges, and
    /// with --field vertices off the surface), for print pipelines and scripts.
    #[arg(long)]
    strict: bool,
    /// Weld vertices within TOL (default 0: coincident) before the analysis, e.g. to see a
    /// non-manifold mesh, whose vertices are duplicated per region pair, as one complex. The
    /// tolerance takes an `=` (`--weld=1e-6`), so `--weld MESH` is never read as one.
    #[arg(
        long,
        value_name = "TOL",
        num_args = 0..=1,
        require_equals = true,
        default_missing_value = "0"
    )]
    weld: Option<f32>,
    /// Also measure how far the vertices lie from this scene's surface (|f| / |∇f| at each
    /// vertex): a mesh of the right topology can still have vertices off the surface.
    #[arg(long, value_name = "SCENE")]
    field: Option<PathBuf>,
    /// With --field: the scene's pose (see `skelform mesh --pose`).
    #[arg(long, requires = "field")]
    pose: Option<String>,
    /// With --field: vertices farther than this from the surface are counted (and, with
    /// --strict, are a defect). Default: 1% of the scene's cell.
    #[arg(long, value_name = "DIST", requires = "field")]
    field_tolerance: Option<f64>,
}

#[derive(Args)]
struct InfoArgs {
    scene: PathBuf,
    /// Also print the compiled instruction tape.
    #[arg(long)]
    tape: bool,
    /// Describe the scene in this named pose (see `skelform mesh --pose`).
    #[arg(long)]
    pose: Option<String>,
    /// Print the description as JSON.
    #[arg(long)]
    json: bool,
}

/// A failure with its exit code.
struct Failure {
    code: u8,
    /// What to print; `None` ends quietly (the reader of standard output has gone).
    error: Option<anyhow::Error>,
}

impl Failure {
    /// The end of a run whose output nobody reads any more: no message, success.
    fn quiet() -> Failure {
        Failure { code: 0, error: None }
    }
}

fn input(error: impl Into<anyhow::Error>) -> Failure {
    Failure { code: 2, error: Some(error.into()) }
}

fn runtime(error: impl Into<anyhow::Error>) -> Failure {
    Failure { code: 1, error: Some(error.into()) }
}

/// A usage error in one line (clap's own spreads over several, with a usage block that
/// scripts and logs cut apart): what is wrong, the accepted values, and where help is.
fn usage_error(e: &clap::Error) -> String {
    let text = e.render().to_string();
    let parts: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| {
            !l.is_empty() && !l.starts_with("Usage:") && !l.starts_with("For more information")
        })
        .map(|l| l.strip_prefix("error: ").unwrap_or(l))
        .collect();
    format!("error: {}; see skelform --help", parts.join(" "))
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => {
            // --help and --version: clap prints them to standard output.
            let text = e.render();
            let shown = if std::io::stdout().is_terminal() {
                text.ansi().to_string()
            } else {
                text.to_string()
            };
            if console::out(format_args!("{shown}")).is_err() {
                return ExitCode::SUCCESS;
            }
            return ExitCode::SUCCESS;
        }
        Err(e) => {
            errln!("{}", usage_error(&e));
            return ExitCode::from(2);
        }
    };
    let result = match cli.command {
        Command::Mesh(a) => mesh(a),
        Command::Check(a) => check(a),
        Command::Info(a) => info(a),
        Command::Extract(a) => extract::extract(a),
        Command::Render(a) => render::render(a),
        Command::Gallery(a) => gallery::gallery(a),
        Command::Animate(a) => animate::animate(a),
        Command::Studio(a) => studio::studio(a),
        Command::Completions { shell } => completions(shell),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            if let Some(e) = f.error {
                errln!("error: {e}");
            }
            ExitCode::from(f.code)
        }
    }
}

fn output_format(path: &Path) -> Result<Format, Failure> {
    Format::from_path(path).ok_or_else(|| {
        input(anyhow!(
            "{}: unknown output format; use a .ply, .obj, .stl or .glb extension",
            path.display()
        ))
    })
}

fn mesh(a: MeshArgs) -> Result<(), Failure> {
    let scene = run::load_scene(&a.scene, a.run.pose.as_deref())?;
    let declared = match &a.output {
        Some(_) => None,
        None => scene.output_file().map_err(run::failure)?.map(Path::to_path_buf),
    };
    let out = a.output.clone().or(declared).ok_or_else(|| {
        input(anyhow!("no output file: give -o OUT.ply (or set [output] file in the scene)"))
    })?;
    let to_stdout = is_stdio(&out);
    let format = match a.format {
        Some(f) => f.into(),
        None if to_stdout => {
            return Err(input(anyhow!("-o - writes to standard output: give its --format")));
        }
        None => output_format(&out)?,
    };
    if to_stdout && (a.json || a.stats) {
        return Err(input(anyhow!(
            "-o - writes the mesh to standard output; --json and --stats would be mixed into it"
        )));
    }
    if let Some(sf) = scene.output.format
        && a.output.is_none()
        && sf != format
    {
        return Err(input(anyhow!(
            "{}: the [output] format does not match the extension of {}",
            scene.origin,
            out.display()
        )));
    }
    let started = Instant::now();
    let meshed = run::run_scene(&scene, &a.run)?;
    run::surface(&scene, &meshed, a.run.quiet)?;
    let mesh = &meshed.mesh;
    let t = Instant::now();
    let write_opts = WriteOptions {
        ascii: a.ascii || scene.output.ascii,
        normals: !a.run.no_normals,
        curves: !a.no_curves,
        ply_curves: a.ply_curves.into(),
    };
    if to_stdout {
        // One stream: a PLY's curves go inline (there is no file beside it), OBJ without
        // a material file.
        let opts = WriteOptions {
            ply_curves: match write_opts.ply_curves {
                PlyCurves::Separate => PlyCurves::Inline,
                other => other,
            },
            ..write_opts
        };
        let mut bytes = Vec::new();
        skelform::mesh::io::write_mesh_to(&mut bytes, mesh, format, &opts).map_err(runtime)?;
        console::out_bytes(&bytes)?;
        return Ok(());
    }
    write_mesh(&out, mesh, format, &write_opts).map_err(runtime)?;
    let writing = t.elapsed();
    let total = started.elapsed();
    if a.json {
        outln!("{}", report::json(&scene, &out, &meshed, writing, total));
    } else if a.stats {
        report::print(&scene, &meshed, writing, total)?;
    }
    if !a.run.quiet && !a.json {
        errln!(
            "wrote {} ({} vertices, {} triangles)",
            out.display(),
            mesh.vertex_count(),
            mesh.triangle_count()
        );
    }
    Ok(())
}

fn completions(shell: clap_complete::Shell) -> Result<(), Failure> {
    let mut script = Vec::new();
    clap_complete::generate(
        shell,
        &mut <Cli as clap::CommandFactory>::command(),
        "skelform",
        &mut script,
    );
    outp!("{}", String::from_utf8_lossy(&script));
    Ok(())
}

fn check(a: CheckArgs) -> Result<(), Failure> {
    let mesh = if is_stdio(&a.mesh) {
        let mut bytes = Vec::new();
        std::io::Read::read_to_end(&mut std::io::stdin().lock(), &mut bytes)
            .map_err(|e| runtime(anyhow!("cannot read standard input: {e}")))?;
        let format = a.format.map_or_else(|| sniff(&bytes), Format::from);
        skelform::mesh::io::read_mesh_from(&bytes, format)
            .map_err(|e| input(anyhow!("standard input: {e}")))?
    } else {
        match a.format {
            Some(f) => skelform::mesh::io::read_mesh_as(&a.mesh, f.into()),
            None => read_mesh(&a.mesh),
        }
        .map_err(input)?
    };
    let report = match a.weld {
        Some(t) if !(t.is_finite() && t >= 0.0) => {
            return Err(input(anyhow!("--weld takes a tolerance of 0 or more")));
        }
        Some(t) => skelform::mesh::check::check_welded(&mesh, t),
        None => skelform::mesh::check::check(&mesh),
    };
    let distance = match &a.field {
        Some(path) => Some(off_surface(&mesh, path, a.pose.as_deref(), a.field_tolerance)?),
        None => None,
    };
    if a.json {
        let mut json = serde_json::to_value(&report)
            .map_err(|e| runtime(anyhow!("cannot serialise the report: {e}")))?;
        if let Some(d) = &distance {
            json["surface_distance"] = serde_json::json!(d);
        }
        let json = serde_json::to_string_pretty(&json)
            .map_err(|e| runtime(anyhow!("cannot serialise the report: {e}")))?;
        outln!("{json}");
    } else {
        outln!("{}", a.mesh.display());
        outp!("{report}");
        if let Some(d) = &distance {
            outln!(
                "off surface   max {:.3e} (vertex {}), mean {:.3e}; {} of {} vertices past {:.3e}{}",
                d.max,
                d.max_at.map_or("-".to_string(), |v| v.to_string()),
                d.mean,
                d.over,
                d.vertices,
                d.tolerance,
                if d.unmeasured > 0 {
                    format!(" ({} where the gradient vanishes)", d.unmeasured)
                } else {
                    String::new()
                }
            );
        }
    }
    let mut defects = report.problems();
    if report.duplicate_faces > 0 {
        defects.push(format!("{} duplicate faces", report.duplicate_faces));
    }
    if report.coincident_faces > 0 {
        defects.push(format!("{} coincident faces", report.coincident_faces));
    }
    if report.folded_edges > 0 {
        defects.push(format!("{} folded edges", report.folded_edges));
    }
    if let Some(d) = distance.as_ref().filter(|d| d.over > 0) {
        defects
            .push(format!("{} vertices off the surface by more than {:.3e}", d.over, d.tolerance));
    }
    if a.strict && !defects.is_empty() {
        return Err(Failure {
            code: 3,
            error: Some(anyhow!(
                "{}: not a clean closed manifold: {}",
                a.mesh.display(),
                defects.join(", ")
            )),
        });
    }
    Ok(())
}

/// How far `mesh`'s vertices lie from the surface of the scene at `path`.
fn off_surface(
    mesh: &skelform::Mesh,
    path: &Path,
    pose: Option<&str>,
    tolerance: Option<f64>,
) -> Result<skelform::SurfaceDistance, Failure> {
    let scene = run::load_scene(path, pose)?;
    if scene.regions_only {
        return Err(input(anyhow!(
            "{}: the scene has [regions] and no [field], so it has no surface to measure against",
            path.display()
        )));
    }
    let tolerance = match tolerance {
        Some(t) if !(t.is_finite() && t >= 0.0) => {
            return Err(input(anyhow!("--field-tolerance takes a distance of 0 or more")));
        }
        Some(t) => t,
        None => 0.01 * scene.lattice(&skelform::Overrides::default()).map_err(run::failure)?.cell,
    };
    Ok(skelform::surface_distance(scene.field.as_ref(), mesh, tolerance))
}

fn info(a: InfoArgs) -> Result<(), Failure> {
    let scene = run::load_scene(&a.scene, a.pose.as_deref())?;
    let lattice = scene.lattice(&skelform::Overrides::default());
    let output = scene.output_file().map(|p| p.map(Path::to_path_buf));
    if a.json {
        let (lo, hi) = (scene.domain.min, scene.domain.max);
        let mut j = serde_json::json!({
            "scene": scene.origin,
            "name": scene.name,
            "description": scene.description,
            "figure": scene.figure,
            "domain": { "min": lo.to_array(), "max": hi.to_array() },
            "method": scene.method.name(),
        });
        j["output"] = match &output {
            Ok(p) => serde_json::json!(p.as_ref().map(|p| p.display().to_string())),
            Err(e) => serde_json::json!({ "refused": e.to_string() }),
        };
        j["grid"] = match &lattice {
            Ok(l) => serde_json::json!({
                "dims": l.dims, "cell": l.cell, "memory_bytes": l.memory(),
                "memory_for": l.need.what(), "streamed": l.streamed(),
            }),
            Err(e) => serde_json::json!({ "invalid": e.to_string() }),
        };
        match &scene.skeleton {
            Some(sk) => {
                j["skeleton"] = serde_json::json!({
                    "elements": sk.element_count(), "blending_sets": sk.clique_count(),
                });
            }
            None => {
                j["iso"] = serde_json::json!(scene.iso);
                j["formula_instructions"] = serde_json::json!(scene.formula.instruction_count());
            }
        }
        if let Some(art) = &scene.articulation {
            j["joints"] = serde_json::json!(art.joints);
            j["pose"] = serde_json::json!(art.pose);
            j["poses"] = serde_json::json!(art.poses);
        }
        if a.tape {
            j["tape"] = serde_json::json!(scene.formula.tape().to_string());
        }
        outln!("{j:#}");
    } else {
        outln!("scene       {}", scene.origin);
        if let Some(n) = &scene.name {
            outln!("name        {n}");
        }
        if let Some(d) = &scene.description {
            outln!("description {d}");
        }
        let (lo, hi) = (scene.domain.min, scene.domain.max);
        outln!("domain      [{}, {}, {}] – [{}, {}, {}]", lo.x, lo.y, lo.z, hi.x, hi.y, hi.z);
        outln!("method      {}", scene.method.name());
        match &output {
            Ok(Some(p)) => outln!("output      {}", p.display()),
            Ok(None) => outln!("output      none (give -o)"),
            Err(e) => outln!("output      refused: {e}"),
        }
        match &lattice {
            Ok(l) => {
                let [nx, ny, nz] = l.dims;
                outln!("grid        {nx} × {ny} × {nz} samples, cell {:.6}", l.cell);
                match l.need {
                    skelform::MemoryNeed::Surface => outln!("memory      {}", l.need.what()),
                    _ => outln!(
                        "memory      {:.1} MiB: {}",
                        l.memory() as f64 / (1 << 20) as f64,
                        l.need.what()
                    ),
                }
            }
            Err(e) => outln!("grid        invalid: {e}"),
        }
        match &scene.skeleton {
            Some(sk) => outln!(
                "skeleton    {} elements in {} blending sets",
                sk.element_count(),
                sk.clique_count()
            ),
            None => {
                outln!("iso         {}", scene.iso);
                outln!("formula     {} instructions", scene.formula.instruction_count());
            }
        }
        if let Some(art) = &scene.articulation {
            outln!("joints      {}", art.joints.len());
            outln!("pose        {} (poses: {})", art.pose, art.poses.join(", "));
        }
        if a.tape {
            outln!("{}", scene.formula.tape());
        }
    }
    // A scene that cannot be meshed at its own settings is bad input, after saying why.
    lattice.map(|_| ()).map_err(run::failure)
}
