//! Pictures of meshes, on the CPU: a z-buffer rasterizer with smooth shading, region
//! colours and a legend, curves drawn over the surface, an optional wireframe, optional
//! transparency, and turntables.
//!
//! What it guarantees:
//! - **Determinism.** The same mesh and [`Settings`] give the same pixels, bit for bit, on
//!   any number of threads: work is split into fixed image tiles, each tile takes its
//!   triangles in mesh order, and nothing is summed across tiles.
//! - **Exact coverage.** Vertices are snapped to 1/256 pixel and coverage is decided in
//!   integers with a top-left rule: neighbouring triangles neither overlap nor leave cracks,
//!   so transparent sheets show no seams.
//! - **The whole form in view.** By default the camera looks at the centre of the bounding
//!   box of the triangles and stands as close as it can while every corner of the box is
//!   inside the image, with a margin ([`Camera::fit`]). A turntable keeps one distance for
//!   all frames.
//! - **Both sides of every sheet.** Nothing is culled: open surfaces and the inner sheets
//!   of non-manifold meshes show, their back sides in a darker colour.
//! - **Clear errors** ([`RenderError`]) for an empty image, a mesh without triangles, an
//!   invalid mesh or non-finite coordinates; never a panic on user data.
//!
//! What it does not do: shadows, reflections or global illumination (one directional light,
//! a constant ambient term and a soft specular highlight); texture filtering beyond
//! bilinear (a mesh's [`Mesh::texture`] is sampled per pixel at its perspective-correct
//! texture coordinates, bilinearly, clamped at the edges, without mipmaps; else its
//! per-vertex colours, [`Mesh::colors`], are drawn: [`Settings::vertex_colours`]);
//! text beyond the legend. Transparency composites every layer exactly, front to back, per
//! pixel (an A-buffer per tile), so it costs memory in proportion to the layers of a tile.
//!
//! ```
//! use skelform_mesh::Mesh;
//! use skelform_render::{render, Settings};
//!
//! // A single triangle facing the default camera.
//! let mesh = Mesh {
//!     positions: vec![[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [0.0, 0.0, 1.0]],
//!     triangles: vec![[0, 1, 2]],
//!     ..Mesh::default()
//! };
//! let settings = Settings { width: 64, height: 48, ..Settings::default() };
//! let image = render(&mesh, &settings)?;
//! assert_eq!((image.width, image.height), (64, 48));
//! // The centre shows the surface, a corner shows the background.
//! assert_ne!(image.pixel(32, 24), settings.background);
//! assert_eq!(image.pixel(0, 0), settings.background);
//! let png: Vec<u8> = image.encode_png()?;
//! assert_eq!(&png[1..4], b"PNG");
//! # Ok::<(), skelform_render::RenderError>(())
//! ```
#![warn(missing_docs)]

mod camera;
mod image;
mod legend;
mod raster;

use std::path::PathBuf;

use rayon::prelude::*;
use skelform_mesh::palette::{SURFACE_COLOUR, region_colour};
use skelform_mesh::{Mesh, MeshError, RegionPair};

pub use camera::{Camera, Projection, View};
pub use image::{Image, Rgb, encode, write_apng};

use legend::Swatch;
use raster::{Look, Prepared, lin};

/// The largest width or height of a picture, in pixels.
pub const MAX_SIDE: u32 = 16384;

/// Why a picture could not be made or written.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("the image size {width}×{height} is empty: width and height must be at least 1")]
    /// A picture with no pixels: [`Settings::width`] or [`Settings::height`] is 0.
    EmptyImage {
        /// The width asked for, in pixels.
        width: u32,
        /// The height asked for, in pixels.
        height: u32,
    },
    #[error("the image size {width}×{height} is too large: at most {MAX_SIDE} pixels a side")]
    /// A side longer than [`MAX_SIDE`] pixels, refused before anything is allocated.
    TooLarge {
        /// The width asked for, in pixels.
        width: u32,
        /// The height asked for, in pixels.
        height: u32,
    },
    /// A mesh with no triangles (points or curves alone): nothing to fit the camera to.
    #[error("the mesh has no triangles to draw")]
    NoTriangles,
    #[error("invalid mesh: {0}")]
    /// The mesh fails [`Mesh::validate`] (an index out of range, lists of the wrong
    /// length, …), so it cannot be drawn safely.
    InvalidMesh(#[from] MeshError),
    #[error("vertex {vertex} has a coordinate that is not a finite number")]
    /// A vertex position with a NaN or infinite coordinate, which would make the fitted
    /// camera meaningless.
    NonFinite {
        /// Index of the first such vertex in `mesh.positions`.
        vertex: usize,
    },
    #[error("invalid settings: {0}")]
    /// A [`Settings`] value out of its range; the message names the setting and the range
    /// ([`Settings::validate`]).
    Settings(String),
    #[error("cannot encode the PNG: {0}")]
    /// The `png` crate could not encode the picture or the animation.
    Encode(#[source] png::EncodingError),
    #[error("cannot write {}: {source}", .path.display())]
    /// Writing the file failed; the file at `path` is left as it was (files are written to
    /// a temporary beside it and renamed over it).
    Write {
        /// The file that was to be written.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },
    #[error("frame {frame}: {message}")]
    /// A frame of an animation ([`write_animation`]) could not be made, for a reason of the
    /// caller's (a pose that does not mesh, say); nothing is written.
    Frame {
        /// The frame, from 0.
        frame: u32,
        /// Why.
        message: String,
    },
}

/// The light: a direction in camera space, and how much ambient, diffuse and specular light
/// there is. Colours are computed in linear light as
/// `albedo·(ambient + diffuse·max(n·l, 0)) + specular·max(n·h, 0)^shininess`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Towards the light, in camera space: `x` right, `y` up, `z` towards the viewer.
    pub direction: [f32; 3],
    /// Light every point receives whatever its normal, as a fraction of its colour
    /// (non-negative; 0.28 by default); keeps the side away from the light readable.
    pub ambient: f32,
    /// Weight of the Lambertian term `max(n·l, 0)` (non-negative; 0.72 by default). With
    /// `ambient + diffuse = 1`, a face turned to the light shows its full colour.
    pub diffuse: f32,
    /// Strength of the white highlight, added to every channel in linear light
    /// (non-negative; 0.18 by default; 0 for a matte picture).
    pub specular: f32,
    /// Blinn–Phong exponent of the highlight: larger is smaller and sharper (40 by
    /// default).
    pub shininess: f32,
}

impl Default for Light {
    /// A key light from the upper left, in front: the usual studio light, which shows the
    /// form's relief without hiding the side away from it (the ambient term keeps it soft).
    fn default() -> Self {
        Light {
            direction: [-0.45, 0.6, 0.65],
            ambient: 0.28,
            diffuse: 0.72,
            specular: 0.18,
            shininess: 40.0,
        }
    }
}

/// Everything about a picture except the mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// Size in pixels, each from 1 to [`MAX_SIDE`].
    pub width: u32,
    /// Height in pixels, 1 to [`MAX_SIDE`]; with `width` it sets the aspect ratio the camera
    /// is fitted to.
    pub height: u32,
    /// The direction the camera looks from; the camera is then fitted to the mesh.
    pub view: View,
    /// The box (low and high corners) the camera is fitted to instead of the mesh's bounds:
    /// the frames of an animation share one camera, so the form moves and the view does not.
    pub fit: Option<([f32; 3], [f32; 3])>,
    /// Perspective (with its field of view, 0–170 degrees) or orthographic.
    pub projection: Projection,
    /// Space left around the fitted box, as a fraction of the half-width and half-height.
    pub margin: f64,
    /// Samples per pixel along each axis (1 to 4): 2 gives smooth edges at 4× the work.
    pub supersample: u32,
    /// Colour of pixels no surface covers, and of what transparent sheets let through.
    pub background: Rgb,
    /// The one directional light and the ambient and specular terms.
    pub light: Light,
    /// Front and back colours of an unlabelled surface.
    pub surface: Rgb,
    /// The back is the side from which the triangles run clockwise (for a closed mesh with
    /// outward winding, the inside). Labelled meshes ignore both: the back of a labelled
    /// sheet is its region colour darkened.
    pub back: Rgb,
    /// Shade a mesh with its own colours instead of `surface` and `back` (or, for a
    /// labelled mesh, its region colours), when it has them: its texture
    /// ([`Mesh::texture`], sampled per pixel at [`Mesh::uvs`]) when it has both, else its
    /// vertex colours ([`Mesh::colors`], interpolated across each triangle); the back in
    /// the same colour, darker.
    pub vertex_colours: bool,
    /// Colours for particular region pairs; others take the shared palette
    /// ([`skelform_mesh::palette::region_colour`]) in the order of the sorted labels.
    pub region_colours: Vec<(RegionPair, Rgb)>,
    /// Draw `mesh.curves` as lines of `curve_width` pixels.
    pub curves: bool,
    /// Colour of the curves (the legend's swatch for them too).
    pub curve_colour: Rgb,
    /// Thickness of the curves in output pixels (more than 0, at most 64); curves are
    /// hidden where the surface is in front of them.
    pub curve_width: f32,
    /// Draw every visible triangle edge.
    pub wireframe: bool,
    /// Colour of the wireframe's lines.
    pub wire_colour: Rgb,
    /// Thickness of the wireframe's lines in output pixels (more than 0, at most 64).
    pub wire_width: f32,
    /// How much a wireframe line covers the shaded surface under it, from 0 (invisible) to
    /// 1 (opaque).
    pub wire_opacity: f32,
    /// See through every sheet: each layer covers `opacity` of what is behind it (more
    /// where seen edge-on), composited exactly front to back.
    pub transparent: bool,
    /// Fraction of what is behind that each transparent layer hides, face-on (more than 0,
    /// at most 1; only with `transparent`).
    pub opacity: f32,
    /// A legend of region colours (and curves) in the top-left corner, for meshes with more
    /// than one label or with curves, in pictures of at least 160 × 120 pixels.
    pub legend: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            width: 800,
            height: 600,
            view: View::default(),
            fit: None,
            projection: Projection::default(),
            margin: 0.08,
            supersample: 2,
            background: [250, 250, 247],
            light: Light::default(),
            surface: SURFACE_COLOUR,
            back: [222, 160, 118],
            vertex_colours: true,
            region_colours: Vec::new(),
            curves: true,
            curve_colour: [25, 25, 35],
            curve_width: 3.0,
            wireframe: false,
            wire_colour: [40, 40, 50],
            wire_width: 1.0,
            wire_opacity: 0.6,
            transparent: false,
            opacity: 0.4,
            legend: true,
        }
    }
}

impl Settings {
    /// Checks every setting, with a message that names the one that is wrong.
    pub fn validate(&self) -> Result<(), RenderError> {
        let (width, height) = (self.width, self.height);
        if width == 0 || height == 0 {
            return Err(RenderError::EmptyImage { width, height });
        }
        if width > MAX_SIDE || height > MAX_SIDE {
            return Err(RenderError::TooLarge { width, height });
        }
        let bad = |m: &str| Err(RenderError::Settings(m.to_string()));
        if !(1..=4).contains(&self.supersample) {
            return bad("supersample must be 1, 2, 3 or 4");
        }
        if !(self.view.azimuth.is_finite() && self.view.elevation.is_finite()) {
            return bad("the view's azimuth and elevation must be finite numbers");
        }
        if !(-90.0..=90.0).contains(&self.view.elevation) {
            return bad("elevation must be between -90 and 90 degrees");
        }
        if let Projection::Perspective { fov_degrees } = self.projection
            && !(fov_degrees > 0.0 && fov_degrees < 170.0)
        {
            return bad("the field of view must be between 0 and 170 degrees");
        }
        if !(self.margin >= 0.0 && self.margin < 0.9) {
            return bad("the margin must be from 0 to 0.9");
        }
        if let Some((lo, hi)) = self.fit
            && !(0..3).all(|a| lo[a].is_finite() && hi[a].is_finite() && lo[a] <= hi[a])
        {
            return bad("the box the camera is fitted to needs finite corners, low below high");
        }
        if !(self.opacity > 0.0 && self.opacity <= 1.0) {
            return bad("opacity must be more than 0 and at most 1");
        }
        if !(self.wire_opacity >= 0.0 && self.wire_opacity <= 1.0) {
            return bad("wire opacity must be from 0 to 1");
        }
        for (what, w) in [("curve", self.curve_width), ("wire", self.wire_width)] {
            if !(w > 0.0 && w <= 64.0) {
                return Err(RenderError::Settings(format!(
                    "{what} width must be more than 0 and at most 64 pixels"
                )));
            }
        }
        let l = self.light;
        let finite = l.direction.iter().all(|c| c.is_finite())
            && [l.ambient, l.diffuse, l.specular, l.shininess]
                .iter()
                .all(|c| c.is_finite() && *c >= 0.0);
        if !finite || l.direction == [0.0; 3] {
            return bad("the light needs a non-zero direction and non-negative finite terms");
        }
        Ok(())
    }
}

/// A mesh made ready to render from any number of views: normals and face colours are
/// computed once.
pub struct Renderer<'m> {
    prepared: Prepared<'m>,
}

impl<'m> Renderer<'m> {
    /// Checks the mesh and computes what every view needs.
    pub fn new(mesh: &'m Mesh) -> Result<Renderer<'m>, RenderError> {
        mesh.validate()?;
        if mesh.triangles.is_empty() {
            return Err(RenderError::NoTriangles);
        }
        if let Some(vertex) = mesh.positions.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(RenderError::NonFinite { vertex });
        }
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for t in &mesh.triangles {
            for &i in t {
                let p = mesh.positions[i as usize];
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
        }
        let face_normals: Vec<[f32; 3]> = mesh
            .triangles
            .par_iter()
            .map(|t| {
                let n = face_normal(mesh, *t);
                let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                if l > 0.0 && l.is_finite() {
                    [(n[0] / l) as f32, (n[1] / l) as f32, (n[2] / l) as f32]
                } else {
                    [0.0; 3]
                }
            })
            .collect();
        let normals =
            if mesh.normals.is_empty() { vertex_normals(mesh) } else { mesh.normals.clone() };
        let (pairs, colour_of) = if mesh.labels.is_empty() {
            (Vec::new(), vec![0; mesh.triangles.len()])
        } else {
            let pairs: Vec<RegionPair> = mesh.label_counts().into_iter().map(|(p, _)| p).collect();
            let colour_of = mesh
                .labels
                .par_iter()
                .map(|l| pairs.binary_search(l).map_or(0, |i| i.min(u16::MAX as usize) as u16))
                .collect();
            (pairs, colour_of)
        };
        // Linear light, as the shading mixes it. A labelled mesh with vertex colours (the
        // leaf's tertiary venation texture) is drawn in them too: they were given on purpose,
        // the region colours are only a default.
        let vertex_colours = mesh.colors.iter().map(|c| c.map(image::to_linear_unit)).collect();
        // A texture replaces the vertex colours where there are texture coordinates to
        // sample it at (the leaf's venation: sharp at any mesh resolution).
        let texture = match &mesh.texture {
            Some(t) if !mesh.uvs.is_empty() => raster::Texels::new(t),
            _ => None,
        };
        Ok(Renderer {
            prepared: Prepared {
                mesh,
                normals,
                face_normals,
                colour_of,
                pairs,
                vertex_colours,
                texture,
                lo,
                hi,
            },
        })
    }

    /// The camera a picture with these settings uses.
    pub fn camera(&self, settings: &Settings) -> Camera {
        let (lo, hi) = self.fitted_box(settings);
        Camera::fit(
            lo,
            hi,
            settings.view,
            settings.projection,
            settings.width,
            settings.height,
            settings.margin,
        )
    }

    /// The box the camera is fitted to: the settings' [`Settings::fit`], else the mesh's.
    fn fitted_box(&self, settings: &Settings) -> ([f32; 3], [f32; 3]) {
        settings.fit.unwrap_or((self.prepared.lo, self.prepared.hi))
    }

    /// The distinct region pairs with the colours the picture gives them, sorted; empty
    /// for an unlabelled mesh.
    pub fn region_colours(&self, settings: &Settings) -> Vec<(RegionPair, Rgb)> {
        self.prepared
            .pairs
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let c = settings
                    .region_colours
                    .iter()
                    .find(|(q, _)| q == p)
                    .map_or_else(|| region_colour(i), |(_, c)| *c);
                (*p, c)
            })
            .collect()
    }

    fn look(&self, s: &Settings) -> Look {
        let (front, back): (Vec<_>, Vec<_>) = if self.prepared.pairs.is_empty() {
            (vec![lin(s.surface)], vec![lin(s.back)])
        } else {
            // The back of a labelled sheet keeps its colour, darker, so the two sides of a
            // sheet are told apart without confusing two labels.
            self.region_colours(s).iter().map(|(_, c)| (lin(*c), lin(*c).map(|v| v * 0.55))).unzip()
        };
        Look {
            front,
            back,
            background: lin(s.background),
            light: s.light.direction,
            ambient: s.light.ambient,
            diffuse: s.light.diffuse,
            specular: s.light.specular,
            shininess: s.light.shininess,
            curve: lin(s.curve_colour),
            wire: lin(s.wire_colour),
        }
    }

    fn legend(&self, s: &Settings) -> Vec<(Swatch, String)> {
        // In a thumbnail the legend would hide the form.
        if !s.legend || s.width < 160 || s.height < 120 {
            return Vec::new();
        }
        let mut entries = Vec::new();
        let colours = self.region_colours(s);
        // Drawn in its vertex colours, a labelled mesh shows no region colours to explain.
        let painted = s.vertex_colours
            && (!self.prepared.vertex_colours.is_empty() || self.prepared.texture.is_some());
        if colours.len() > 1 && !painted {
            entries.push((Swatch::None, "regions".to_string()));
            for (p, c) in colours {
                entries.push((Swatch::Fill(c), format!("{}-{}", p.0, p.1)));
            }
        }
        if s.curves && !self.prepared.mesh.curves.is_empty() {
            entries.push((Swatch::Line(s.curve_colour), "curves".to_string()));
        }
        entries
    }

    /// One picture.
    pub fn render(&self, settings: &Settings) -> Result<Image, RenderError> {
        settings.validate()?;
        let look = self.look(settings);
        let mut img = raster::render_view(&self.prepared, settings, &look, self.camera(settings));
        legend::draw(&mut img, &self.legend(settings));
        Ok(img)
    }

    /// `frames` pictures turning once around the vertical (`z`) axis, starting at the
    /// settings' azimuth, all at one camera distance so the form keeps its size. Holds every
    /// frame: for long or large animations [`Renderer::write_turntable`] holds one at a time.
    pub fn turntable(&self, settings: &Settings, frames: u32) -> Result<Vec<Image>, RenderError> {
        let draw = self.turntable_frames(settings, frames)?;
        Ok((0..frames).map(draw).collect())
    }

    /// Writes the turntable of [`Renderer::turntable`] as an animated PNG at `path`
    /// (atomically), each frame shown `delay_ms` milliseconds, drawing and encoding one frame
    /// at a time, so memory does not grow with the frame count.
    pub fn write_turntable(
        &self,
        settings: &Settings,
        frames: u32,
        delay_ms: u16,
        path: &std::path::Path,
    ) -> Result<(), RenderError> {
        let draw = self.turntable_frames(settings, frames)?;
        image::write_apng_streamed(path, (settings.width, settings.height), frames, delay_ms, |k| {
            Ok(draw(k))
        })
    }

    /// The frame-drawing function of a turntable of `frames` views.
    fn turntable_frames(
        &self,
        settings: &Settings,
        frames: u32,
    ) -> Result<impl Fn(u32) -> Image + '_, RenderError> {
        settings.validate()?;
        if frames == 0 || frames > MAX_FRAMES {
            return Err(RenderError::Settings(format!(
                "a turntable needs from 1 to {MAX_FRAMES} frames"
            )));
        }
        let p = &self.prepared;
        let views: Vec<View> = (0..frames)
            .map(|k| View {
                azimuth: settings.view.azimuth + 360.0 * f64::from(k) / f64::from(frames),
                elevation: settings.view.elevation,
            })
            .collect();
        let (lo, hi) = self.fitted_box(settings);
        let (_, cams) = Camera::fit_views(
            lo,
            hi,
            &views,
            settings.projection,
            settings.width,
            settings.height,
            settings.margin,
        );
        let look = self.look(settings);
        let entries = self.legend(settings);
        let settings = settings.clone();
        Ok(move |k: u32| {
            let mut img = raster::render_view(p, &settings, &look, cams[k as usize]);
            legend::draw(&mut img, &entries);
            img
        })
    }
}

/// Writes an animated PNG at `path` (atomically) of `count` frames that `frame(k)` makes one
/// at a time, each shown `delay_ms` milliseconds and dropped once encoded, so memory does not
/// grow with the count. Every frame must be `size` pixels. The first error, the caller's
/// ([`RenderError::Frame`]) or the encoder's, stops the animation and leaves `path` as it was.
pub fn write_animation(
    path: &std::path::Path,
    size: (u32, u32),
    count: u32,
    delay_ms: u16,
    frame: impl FnMut(u32) -> Result<Image, RenderError>,
) -> Result<(), RenderError> {
    if count == 0 || count > MAX_FRAMES {
        return Err(RenderError::Settings(format!(
            "an animation needs from 1 to {MAX_FRAMES} frames (got {count})"
        )));
    }
    image::write_apng_streamed(path, size, count, delay_ms, frame)
}

/// The most frames an animation or turntable may have.
pub const MAX_FRAMES: u32 = 3600;

/// Renders `mesh` as `settings` say, on the current rayon thread pool.
pub fn render(mesh: &Mesh, settings: &Settings) -> Result<Image, RenderError> {
    Renderer::new(mesh)?.render(settings)
}

/// The right-hand normal of a triangle, with the length of twice its area (in `f64`).
fn face_normal(mesh: &Mesh, t: [u32; 3]) -> [f64; 3] {
    let p = t.map(|i| mesh.positions[i as usize].map(f64::from));
    let (u, v) = (
        [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]],
        [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]],
    );
    [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
}

/// Area-weighted vertex normals from the winding, for meshes that carry none; summed in
/// triangle order, so the result does not depend on threads.
fn vertex_normals(mesh: &Mesh) -> Vec<[f32; 3]> {
    let mut acc = vec![[0.0f64; 3]; mesh.positions.len()];
    for t in &mesh.triangles {
        let n = face_normal(mesh, *t);
        for &i in t {
            for k in 0..3 {
                acc[i as usize][k] += n[k];
            }
        }
    }
    acc.iter()
        .map(|n| {
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if l > 0.0 {
                [(n[0] / l) as f32, (n[1] / l) as f32, (n[2] / l) as f32]
            } else {
                [0.0; 3]
            }
        })
        .collect()
}
