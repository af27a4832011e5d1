//! `skelform render`: a picture of a scene (meshed first, with the same options as
//! `skelform mesh`) or of a mesh file, by the input's extension.

use std::path::{Path, PathBuf};

use anyhow::anyhow;
use clap::Args;
use skelform::Mesh;
use skelform::mesh::io::read_mesh;
use skelform::render::{Projection, RenderError, Renderer, Settings, View};

use crate::{Failure, input, run, runtime};

#[derive(Args)]
pub struct RenderArgs {
    /// A scene (.toml, meshed first) or a mesh (.ply, .obj, .stl, .glb).
    pub input: PathBuf,
    /// The picture to write (.png).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Picture size in pixels, WIDTHxHEIGHT.
    #[arg(long, value_parser = parse_size, default_value = "800x600")]
    pub size: (u32, u32),
    /// Where the camera looks from: azimuth,elevation in degrees. Azimuth 0 looks from −y
    /// towards +y with z up; 90 looks from +x. Elevation 90 looks straight down.
    #[arg(long, value_parser = parse_view, allow_hyphen_values = true, default_value = "30,25")]
    pub view: (f64, f64),
    /// Write an animated PNG of N frames turning once about the z axis.
    #[arg(long, value_name = "N")]
    pub turntable: Option<u32>,
    /// Milliseconds each turntable frame is shown.
    #[arg(long, default_value_t = 80, requires = "turntable")]
    pub frame_ms: u16,
    /// Draw every triangle edge over the surface.
    #[arg(long)]
    pub wireframe: bool,
    /// See through the surfaces, so inner sheets show.
    #[arg(long)]
    pub transparent: bool,
    /// How much each sheet covers what is behind it, with --transparent (0 to 1).
    #[arg(long, default_value_t = 0.4, requires = "transparent")]
    pub opacity: f32,
    /// Leave out the intersection curves.
    #[arg(long)]
    pub no_curves: bool,
    /// Width of the curves in pixels.
    #[arg(long, default_value_t = 3.0)]
    pub curve_width: f32,
    /// Leave out the legend of region colours.
    #[arg(long)]
    pub no_legend: bool,
    /// Parallel projection instead of perspective.
    #[arg(long)]
    pub orthographic: bool,
    /// Perspective field of view across the shorter side, in degrees.
    #[arg(long, default_value_t = 30.0, conflicts_with = "orthographic")]
    pub fov: f64,
    /// Samples per pixel along each axis, 1 to 4 (2 smooths edges).
    #[arg(long, default_value_t = 2)]
    pub supersample: u32,
    /// Background colour, RRGGBB in hex.
    #[arg(long, value_parser = parse_colour, default_value = "fafaf7")]
    pub background: [u8; 3],
    #[command(flatten)]
    pub run: run::RunArgs,
}

/// The picture settings the arguments describe, for a picture of `size`.
pub fn settings(a: &RenderArgs) -> Settings {
    Settings {
        width: a.size.0,
        height: a.size.1,
        view: View { azimuth: a.view.0, elevation: a.view.1 },
        projection: if a.orthographic {
            Projection::Orthographic
        } else {
            Projection::Perspective { fov_degrees: a.fov }
        },
        supersample: a.supersample,
        background: a.background,
        curves: !a.no_curves,
        curve_width: a.curve_width,
        wireframe: a.wireframe,
        transparent: a.transparent,
        opacity: a.opacity,
        legend: !a.no_legend,
        ..Settings::default()
    }
}

/// Bad settings and bad meshes are the user's input (exit 2); failing to write is a
/// runtime failure (exit 1).
pub fn failure(e: RenderError) -> Failure {
    match e {
        RenderError::Write { .. } | RenderError::Encode(_) => runtime(e),
        _ => input(e),
    }
}

/// The mesh to draw: a scene meshed as `skelform mesh` would, or a mesh file.
pub fn load(path: &Path, run_args: &run::RunArgs) -> Result<Mesh, Failure> {
    let is_scene = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    let mesh = if is_scene {
        let scene = run::load_scene(path, run_args.pose.as_deref())?;
        let meshed = run::run_scene(&scene, run_args)?;
        run::surface(&scene, &meshed, run_args.quiet)?;
        meshed.mesh
    } else {
        read_mesh(path).map_err(input)?
    };
    if mesh.triangles.is_empty() {
        return Err(input(anyhow!("{}: the mesh has no triangles to draw", path.display())));
    }
    Ok(mesh)
}

pub fn render(a: RenderArgs) -> Result<(), Failure> {
    if !a.output.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
        return Err(input(anyhow!(
            "{}: pictures are written as PNG; give the output a .png extension",
            a.output.display()
        )));
    }
    let s = settings(&a);
    // Settings first: a bad size or view should not wait for a scene to be meshed.
    s.validate().map_err(failure)?;
    let mesh = load(&a.input, &a.run)?;
    let pool = run::pool(&a.run)?;
    let with_input = |e: RenderError| {
        let f = failure(e);
        Failure { code: f.code, error: f.error.map(|e| anyhow!("{}: {e}", a.input.display())) }
    };
    pool.install(|| {
        let renderer = Renderer::new(&mesh).map_err(with_input)?;
        match a.turntable {
            Some(n) => renderer.write_turntable(&s, n, a.frame_ms, &a.output).map_err(failure),
            None => renderer.render(&s).map_err(failure)?.write_png(&a.output).map_err(failure),
        }
    })?;
    if !a.run.quiet {
        let frames = a.turntable.map_or(String::new(), |n| format!(", {n} frames"));
        errln!("wrote {} ({}×{}{frames})", a.output.display(), s.width, s.height);
    }
    Ok(())
}

/// `WIDTHxHEIGHT` (or with `×`), each at least 1.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let parts: Vec<&str> = s.split(['x', 'X', '×']).map(str::trim).collect();
    let (w, h) = match parts[..] {
        [w, h] => (w.parse::<u32>(), h.parse::<u32>()),
        _ => return Err(format!("'{s}' is not a size like 800x600")),
    };
    match (w, h) {
        (Ok(w), Ok(h)) if w >= 1 && h >= 1 => Ok((w, h)),
        (Ok(_), Ok(_)) => {
            Err(format!("the image size '{s}' is empty: width and height must be at least 1"))
        }
        _ => Err(format!("'{s}' is not a size like 800x600")),
    }
}

pub fn parse_view(s: &str) -> Result<(f64, f64), String> {
    let nums: Vec<Option<f64>> = s.split(',').map(|p| p.trim().parse().ok()).collect();
    match nums[..] {
        [Some(az), Some(el)] if az.is_finite() && (-90.0..=90.0).contains(&el) => Ok((az, el)),
        [Some(_), Some(_)] => Err(format!("'{s}': elevation must be from -90 to 90 degrees")),
        _ => Err(format!("'{s}' is not a view like 30,25 (azimuth,elevation in degrees)")),
    }
}

fn parse_colour(s: &str) -> Result<[u8; 3], String> {
    let hex = s.trim_start_matches('#');
    let ok = hex.len() == 6 && hex.chars().all(|c| c.is_ascii_hexdigit());
    let byte = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).ok();
    match (ok, ok.then(|| [byte(0), byte(2), byte(4)])) {
        (true, Some([Some(r), Some(g), Some(b)])) => Ok([r, g, b]),
        _ => Err(format!("'{s}' is not a colour like fafaf7 (RRGGBB in hex)")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_views_and_colours() {
        assert_eq!(parse_size("480x360"), Ok((480, 360)));
        assert_eq!(parse_size("480×360"), Ok((480, 360)));
        assert!(parse_size("0x360").unwrap_err().contains("empty"));
        assert!(parse_size("480").is_err());
        assert_eq!(parse_view("-30,10"), Ok((-30.0, 10.0)));
        assert!(parse_view("0,100").is_err());
        assert_eq!(parse_colour("#ff8000"), Ok([255, 128, 0]));
        assert!(parse_colour("ff80").is_err());
    }
}
