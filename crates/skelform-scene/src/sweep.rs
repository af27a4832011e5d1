//! `[[skeleton.sweep]]`: generalized cylinders (DIS §5.3–5.5), parsed and validated into
//! [`skelform_skeleton::Sweep`]s. Kept apart from `skeleton.rs` because a sweep is not an
//! element of the [`skelform_skeleton::Skeleton`]: it is added to the skeleton's field by
//! [`skelform_skeleton::SweptField`].

use std::path::Path;
use std::sync::Arc;

use serde::Deserialize;
use skelform_field::DVec3;
use skelform_skeleton::sweep::{MAX_SECTION_PIXELS, SectionImage};
use skelform_skeleton::{Sweep, SweepSettings};
use toml::Spanned;

use crate::SceneError;
use crate::diag::At;

/// One `[[skeleton.sweep]]` table.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SweepSpec {
    /// The four Bézier control points of the curve swept along.
    points: Spanned<Vec<[f64; 3]>>,
    /// `"circle"` (default), `"ellipse"` or `"image"` (the default when `section_image` is
    /// given).
    section: Option<Spanned<String>>,
    /// A grayscale PNG whose light pixels are the section, over `[−a, a] × [−b, b]`;
    /// relative to the scene file's folder.
    section_image: Option<Spanned<String>>,
    /// Circle: one radius, or one per control point.
    radius: Option<Spanned<OneOrList<f64>>>,
    /// Ellipse: one `[a, b]` pair, or one per control point (`a` along the frame's normal,
    /// `b` along its binormal).
    radii: Option<Spanned<OneOrList<[f64; 2]>>>,
    /// Hemispherical caps at the ends (default true); false leaves flat ends.
    caps: Option<Spanned<bool>>,
    /// The first frame's normal, which orients the ellipse; default: any.
    normal: Option<Spanned<[f64; 3]>>,
    /// Weight of the sweep's density under the sum and convolution blends (default 1).
    strength: Option<Spanned<f64>>,
}

/// A value, or a list of them.
#[derive(Deserialize)]
#[serde(untagged)]
enum OneOrList<T> {
    One(T),
    List(Vec<T>),
}

impl<T: Copy> OneOrList<T> {
    fn as_slice(&self) -> &[T] {
        match self {
            OneOrList::One(v) => std::slice::from_ref(v),
            OneOrList::List(v) => v,
        }
    }
}

/// One value, or four (one per control point), from `list`.
fn per_point<T: Copy>(list: &[T], at: At, offset: usize, key: &str) -> Result<[T; 4], SceneError> {
    match list.len() {
        1 => Ok([list[0]; 4]),
        4 => Ok([list[0], list[1], list[2], list[3]]),
        n => Err(at(offset, format!("{key}: give one value or four (one per point), got {n}"))),
    }
}

/// The most bytes a section image file may have, checked before it is read: a PNG of the
/// largest size, [`MAX_SECTION_PIXELS`] on a side, in 16-bit RGBA without compression
/// takes 8 MiB.
pub const MAX_SECTION_FILE_BYTES: u64 = 16 << 20;

#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Circle,
    Ellipse,
    Image,
}

/// A PNG read for a scene: width, height, and per pixel its lightness (Rec. 709 luma for
/// colour images) and opacity, both from 0 to 255, row 0 at the top.
pub(crate) struct Png {
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) pixels: Vec<(f64, f64)>,
}

/// The scene keys whose values name files that parsing reads (every file a scene can make
/// the library open, besides the scene itself): a front end that must keep a scene inside
/// its folder (the studio) checks exactly these. The reader takes only these names.
pub const FILE_KEYS: &[&str] = &[FileKey::SectionImage.name(), FileKey::WeightImage.name()];

/// A key of [`FILE_KEYS`]: the only way to ask for a file to be read.
#[derive(Clone, Copy)]
pub(crate) enum FileKey {
    /// A sweep's cross-section drawn as an image.
    SectionImage,
    /// A polygon's weights drawn as an image.
    WeightImage,
}

impl FileKey {
    pub(crate) const fn name(self) -> &'static str {
        match self {
            FileKey::SectionImage => "section_image",
            FileKey::WeightImage => "weight_image",
        }
    }
}

/// Reads the PNG `name` (relative to `base`, the scene's folder) for the key `key`,
/// checking its file size and dimensions (2 ..= `max_side` on a side) before decoding;
/// errors at `offset`, naming the key and the file.
pub(crate) fn read_png(
    name: &str,
    base: Option<&Path>,
    at: At,
    offset: usize,
    key: FileKey,
    max_side: usize,
) -> Result<Png, SceneError> {
    let key = key.name();
    let path = match base {
        Some(dir) if Path::new(name).is_relative() => dir.join(name),
        _ => Path::new(name).to_path_buf(),
    };
    let shown = path.display();
    let fail = |m: String| at(offset, format!("{key} '{shown}': {m}"));
    let file = std::fs::File::open(&path).map_err(|e| fail(format!("cannot open it: {e}")))?;
    let bytes = file.metadata().map_err(|e| fail(format!("cannot read it: {e}")))?.len();
    if bytes > MAX_SECTION_FILE_BYTES {
        return Err(fail(format!(
            "the file has {bytes} bytes, over the limit of {MAX_SECTION_FILE_BYTES}"
        )));
    }
    let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
    let info =
        decoder.read_header_info().map_err(|e| fail(format!("not a readable PNG image: {e}")))?;
    let (w, h) = (info.width as usize, info.height as usize);
    if w.max(h) > max_side || w.min(h) < 2 {
        return Err(fail(format!(
            "the image is {w}x{h} pixels; a {key} is 2 to {max_side} on a side"
        )));
    }
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader =
        decoder.read_info().map_err(|e| fail(format!("not a readable PNG image: {e}")))?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| fail("the image is too large to decode".to_string()))?;
    let mut buf = vec![0; size];
    let frame =
        reader.next_frame(&mut buf).map_err(|e| fail(format!("cannot decode the image: {e}")))?;
    let channels = frame.color_type.samples();
    let (fw, fh) = (frame.width as usize, frame.height as usize);
    let mut pixels = Vec::with_capacity(fw * fh);
    for r in 0..fh {
        let row = &buf[r * frame.line_size..][..fw * channels];
        for px in row.chunks_exact(channels) {
            pixels.push(match px {
                [g] => (f64::from(*g), 255.0),
                [g, a] => (f64::from(*g), f64::from(*a)),
                [r, g, b] => (
                    0.2126 * f64::from(*r) + 0.7152 * f64::from(*g) + 0.0722 * f64::from(*b),
                    255.0,
                ),
                [r, g, b, a, ..] => (
                    0.2126 * f64::from(*r) + 0.7152 * f64::from(*g) + 0.0722 * f64::from(*b),
                    f64::from(*a),
                ),
                [] => (0.0, 0.0),
            });
        }
    }
    Ok(Png { width: fw, height: fh, pixels })
}

/// Reads the section image `name` (relative to `base`); errors at `offset`.
fn load_section(
    name: &str,
    base: Option<&Path>,
    at: At,
    offset: usize,
) -> Result<SectionImage, SceneError> {
    let png = read_png(name, base, at, offset, FileKey::SectionImage, MAX_SECTION_PIXELS)?;
    // A pixel is inside when it is at least half light (and at least half opaque).
    let inside: Vec<bool> =
        png.pixels.iter().map(|&(light, alpha)| light >= 127.5 && alpha >= 127.5).collect();
    SectionImage::from_mask(png.width, png.height, &inside)
        .map_err(|e| at(offset, format!("section_image '{name}': {e}")))
}

/// The sweeps of a skeleton section; section images are read relative to `base` (the
/// current folder when `None`).
pub(crate) fn build(
    specs: &[SweepSpec],
    at: At,
    base: Option<&Path>,
) -> Result<Vec<Sweep>, SceneError> {
    let mut out = Vec::with_capacity(specs.len());
    for sp in specs {
        let pat = sp.points.span().start;
        let pts = sp.points.get_ref();
        if pts.len() != 4 {
            return Err(at(
                pat,
                format!("points: a sweep takes 4 Bézier control points, got {}", pts.len()),
            ));
        }
        let control = [0, 1, 2, 3].map(|i| DVec3::from_array(pts[i]));
        let kind = match (&sp.section, &sp.section_image) {
            (None, None) => Kind::Circle,
            (None, Some(_)) => Kind::Image,
            (Some(s), _) => match s.get_ref().as_str() {
                "circle" => Kind::Circle,
                "ellipse" => Kind::Ellipse,
                "image" => Kind::Image,
                other => {
                    return Err(at(
                        s.span().start,
                        format!("unknown section '{other}'; expected circle, ellipse or image"),
                    ));
                }
            },
        };
        match (kind, &sp.section_image, &sp.section) {
            (Kind::Image, None, Some(s)) => {
                return Err(at(
                    s.span().start,
                    "section = \"image\" needs section_image = \"FILE.png\"".into(),
                ));
            }
            (Kind::Circle | Kind::Ellipse, Some(i), _) => {
                return Err(at(
                    i.span().start,
                    "section_image is for section = \"image\" (or no section key)".into(),
                ));
            }
            _ => {}
        }
        let image_radii = match (kind, &sp.radius, &sp.radii) {
            (Kind::Image, Some(_), Some(r)) => {
                return Err(at(r.span().start, "give radius or radii, not both".into()));
            }
            (Kind::Image, Some(r), None) => Some(
                per_point(r.get_ref().as_slice(), at, r.span().start, "radius")?.map(|r| [r, r]),
            ),
            (Kind::Image, None, Some(r)) => {
                Some(per_point(r.get_ref().as_slice(), at, r.span().start, "radii")?)
            }
            (Kind::Image, None, None) => {
                return Err(at(
                    pat,
                    "an image section needs radius (or radii = [[a, b], ...]): the image's \
                     half-width and half-height"
                        .into(),
                ));
            }
            _ => None,
        };
        let ellipse = kind == Kind::Ellipse;
        let radii: [[f64; 2]; 4] = match (ellipse, &sp.radius, &sp.radii) {
            _ if kind == Kind::Image => image_radii.unwrap_or([[1.0; 2]; 4]),
            (false, Some(r), None) => {
                per_point(r.get_ref().as_slice(), at, r.span().start, "radius")?.map(|r| [r, r])
            }
            (true, None, Some(r)) => {
                per_point(r.get_ref().as_slice(), at, r.span().start, "radii")?
            }
            (false, _, Some(r)) => {
                return Err(at(
                    r.span().start,
                    "radii (two per point) is for section = \"ellipse\"; a circle takes radius"
                        .into(),
                ));
            }
            (true, Some(r), _) => {
                return Err(at(
                    r.span().start,
                    "an ellipse takes radii = [[a, b], ...], not radius".into(),
                ));
            }
            (false, None, None) => return Err(at(pat, "a circular sweep needs radius".into())),
            (true, None, None) => {
                return Err(at(pat, "an elliptical sweep needs radii = [[a, b], ...]".into()));
            }
        };
        let normal = match &sp.normal {
            Some(n) => {
                let v = DVec3::from_array(*n.get_ref());
                if !v.is_finite() || v.length() == 0.0 {
                    return Err(at(n.span().start, "normal must be a non-zero vector".into()));
                }
                Some(v)
            }
            None => None,
        };
        let settings = SweepSettings {
            caps: sp.caps.as_ref().is_none_or(|c| *c.get_ref()),
            initial_normal: normal,
            ..SweepSettings::default()
        };
        let strength = sp.strength.as_ref().map_or(1.0, |w| *w.get_ref());
        // Read only once everything written in the table is known good.
        let image = match &sp.section_image {
            Some(i) => Some(Arc::new(load_section(i.get_ref(), base, at, i.span().start)?)),
            None => None,
        };
        let sweep = Sweep::new(control, radii, strength, settings).map_err(|e| {
            let offset = match (&e, &sp.strength, &sp.radius, &sp.radii) {
                (skelform_skeleton::SkeletonError::BadStrength(_), Some(w), _, _) => w.span().start,
                (skelform_skeleton::SkeletonError::BadRadius(_), _, Some(r), _) => r.span().start,
                (skelform_skeleton::SkeletonError::BadRadius(_), _, _, Some(r)) => r.span().start,
                _ => pat,
            };
            at(offset, e.to_string())
        })?;
        if let Some(n) = normal
            && n.cross(sweep.curve().velocity(0.0)).length() == 0.0
        {
            return Err(at(
                sp.normal.as_ref().map_or(pat, |n| n.span().start),
                "normal is along the curve's start tangent; it must point across the curve".into(),
            ));
        }
        out.push(match image {
            Some(im) => sweep.with_image(im),
            None => sweep,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use crate::Scene;
    use skelform_field::{DVec3, Field};
    use skelform_mesh::check::check;
    use skelform_polygonize::LatticeOptions;
    use skelform_polygonize::grid::{Options, polygonize};

    const HEAD: &str = "[domain]\nmin = [-1, -1, -1]\nmax = [2, 2, 2]\n[skeleton]\n";

    fn error(body: &str) -> (usize, usize, String) {
        crate::testing::error_position(Scene::parse(&format!("{HEAD}{body}"), "s.toml"), body)
    }

    #[test]
    fn bad_sweeps_are_refused_with_their_position() {
        let pts = "points = [[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]]\n";
        let (l, c, m) =
            error("[[skeleton.sweep]]\npoints = [[0, 0, 0], [1, 1, 1]]\nradius = [0.1]\n");
        assert_eq!((l, c), (6, 10), "{m}");
        assert!(m.contains("4 Bézier control points"), "{m}");
        let (l, _, m) = error(&format!("[[skeleton.sweep]]\n{pts}radius = [0.1, 0.2]\n"));
        assert_eq!(l, 7, "{m}");
        assert!(m.contains("one value or four"), "{m}");
        let (l, _, m) = error(&format!("[[skeleton.sweep]]\n{pts}radius = [0.1, 0, 0.1, 0.1]\n"));
        assert_eq!(l, 7, "{m}");
        let (l, _, m) =
            error(&format!("[[skeleton.sweep]]\n{pts}section = \"square\"\nradius = [0.1]\n"));
        assert_eq!(l, 7, "{m}");
        assert!(m.contains("circle, ellipse or image"), "{m}");
        let (l, _, m) =
            error(&format!("[[skeleton.sweep]]\n{pts}section = \"ellipse\"\nradius = [0.1]\n"));
        assert_eq!(l, 8, "{m}");
        let (l, _, m) = error(&format!("[[skeleton.sweep]]\n{pts}radii = [[0.1, 0.2]]\n"));
        assert_eq!(l, 7, "{m}");
        let (l, _, m) =
            error(&format!("[[skeleton.sweep]]\n{pts}radius = [0.1]\nnormal = [0, 1, 0]\n"));
        assert_eq!(l, 8, "{m}");
        assert!(m.contains("across the curve"), "{m}");
        let (l, _, m) = error(&format!("[[skeleton.sweep]]\n{pts}radius = [0.1]\nwidth = 2\n"));
        assert_eq!(l, 8, "{m}");
    }

    #[test]
    fn a_sweep_alone_is_a_scene() {
        let s = Scene::parse(
            &format!(
                "{HEAD}[[skeleton.sweep]]\npoints = [[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]]\nradius = 0.1\n"
            ),
            "s.toml",
        );
        assert!(s.is_ok(), "a single radius");
        let s = Scene::parse(
            &format!(
                "{HEAD}[[skeleton.sweep]]\npoints = [[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]]\nradius = [0.1]\n"
            ),
            "s.toml",
        )
        .unwrap();
        assert!(s.skeleton.is_none());
        // On the curve inside, one radius off it on the surface (the start's tangent is +y,
        // so +x is across the curve there).
        assert!(s.field.eval(DVec3::ZERO) < 0.0);
        assert!(s.field.eval(DVec3::new(0.1, 0.0, 0.0)).abs() < 1e-9);
        assert!(s.field.eval(DVec3::new(0.0, -0.1, 0.0)).abs() < 1e-9, "the cap");
        assert!(!s.continuation.seeds.is_empty());
    }

    /// A grayscale PNG of `w × h` pixels at a fresh path in the temporary folder.
    fn png_file(name: &str, w: u32, h: u32, value: impl Fn(u32, u32) -> u8) -> std::path::PathBuf {
        crate::testing::grayscale_png("skelform-sweep", name, w, h, value)
    }

    #[test]
    fn bad_section_images_are_refused_with_their_position() {
        let pts = "points = [[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]]\n";
        let (l, c, m) = error(&format!(
            "[[skeleton.sweep]]\n{pts}section_image = \"no-such-file.png\"\nradius = 0.1\n"
        ));
        assert_eq!((l, c), (7, 17), "{m}");
        assert!(m.contains("no-such-file.png") && m.contains("cannot open"), "{m}");
        // Over the size limit: refused from the header, before decoding.
        let big = png_file("big.png", 2000, 4, |_, _| 255);
        let (l, _, m) = error(&format!(
            "[[skeleton.sweep]]\n{pts}section_image = {:?}\nradius = 0.1\n",
            big.display().to_string()
        ));
        assert_eq!(l, 7, "{m}");
        assert!(m.contains("2000x4 pixels") && m.contains("2 to 1024"), "{m}");
        // No pixel inside.
        let dark = png_file("dark.png", 8, 8, |_, _| 20);
        let (l, _, m) = error(&format!(
            "[[skeleton.sweep]]\n{pts}section_image = {:?}\nradius = 0.1\n",
            dark.display().to_string()
        ));
        assert_eq!(l, 7, "{m}");
        assert!(m.contains("no pixel inside"), "{m}");
        // Not a PNG.
        let text = big.with_file_name("text.png");
        std::fs::write(&text, "not an image").unwrap();
        let (_, _, m) = error(&format!(
            "[[skeleton.sweep]]\n{pts}section_image = {:?}\nradius = 0.1\n",
            text.display().to_string()
        ));
        assert!(m.contains("not a readable PNG"), "{m}");
        // The keys that go with an image section.
        let (l, _, m) =
            error(&format!("[[skeleton.sweep]]\n{pts}section = \"image\"\nradius = 0.1\n"));
        assert_eq!(l, 7, "{m}");
        assert!(m.contains("needs section_image"), "{m}");
        let (l, _, m) = error(&format!(
            "[[skeleton.sweep]]\n{pts}section = \"ellipse\"\nsection_image = \"x.png\"\nradii = [[0.1, 0.2]]\n"
        ));
        assert_eq!(l, 8, "{m}");
        assert!(m.contains("section_image is for section = \"image\""), "{m}");
        let (l, _, m) = error(&format!("[[skeleton.sweep]]\n{pts}section_image = \"x.png\"\n"));
        assert_eq!(l, 6, "{m}");
        assert!(m.contains("needs radius"), "{m}");
        let _ = std::fs::remove_dir_all(big.parent().unwrap());
    }

    /// An example scene, meshed by the grid at its own resolution.
    fn example(name: &str) -> (Scene, skelform_mesh::Mesh) {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples/skeleton")
            .join(name);
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let lattice = LatticeOptions {
            domain: scene.domain,
            resolution: scene.resolution,
            ..Default::default()
        };
        let (mesh, _) =
            polygonize(&*scene.field, &Options { lattice, ..Default::default() }).unwrap();
        (scene, mesh)
    }

    /// The star example's mesh has the image's shape: vertices in the middle of the sweep,
    /// in the section's normalised coordinates, lie where the mask changes from inside to
    /// outside (inside and outside pixels both within a cell and a pixel), and reach the
    /// star's tips and notches.
    #[test]
    fn an_image_section_meshes_to_the_image_shape() {
        let (scene, mesh) = example("star-sweep.toml");
        let r = check(&mesh);
        assert_eq!(r.components.len(), 1);
        let c = &r.components[0];
        assert!(c.closed && c.orientable && c.inconsistent_edges == 0 && c.euler == 2);
        let cell = (scene.domain.max - scene.domain.min).max_element() / 127.0;
        let sweep = &scene.sweeps.as_ref().unwrap().sweeps()[0];
        let image = sweep.image().unwrap();
        let (w, h) = image.size();
        assert_eq!((w, h), (64, 64));
        // The mask, read back independently of the distance table.
        let mask = |x: f64, y: f64| -> Option<bool> {
            let c = ((x + 1.0) * 0.5 * w as f64).floor();
            let r = ((1.0 - y) * 0.5 * h as f64).floor();
            (c >= 0.0 && r >= 0.0 && (c as usize) < w && (r as usize) < h)
                .then(|| image.inside(c as usize, r as usize))
        };
        let (mut n, mut reach) = (0, (f64::INFINITY, 0.0_f64));
        for p in &mesh.positions {
            let p = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            let l = sweep.locate(p);
            if !(0.35..=0.65).contains(&l.t) || l.s != 0.0 {
                continue;
            }
            let (x, y) = (l.x / l.radii[0], l.y / l.radii[1]);
            // A cell in normalised units, and a pixel (2 / 64).
            let tol = cell / l.radii[0] + 2.0 / w as f64;
            let (mut inside, mut outside) = (false, false);
            for k in 0..32 {
                let a = k as f64 * std::f64::consts::TAU / 32.0;
                for f in [0.0, 0.5, 1.0] {
                    match mask(x + f * tol * a.cos(), y + f * tol * a.sin()) {
                        Some(true) => inside = true,
                        _ => outside = true,
                    }
                }
            }
            assert!(inside && outside, "{p}: ({x:.3}, {y:.3}) is not on the star's boundary");
            let rad = (x * x + y * y).sqrt();
            reach = (reach.0.min(rad), reach.1.max(rad));
            n += 1;
        }
        assert!(n > 300, "{n} vertices checked");
        // The star's tips and notches: the farthest inside pixel centre and the nearest
        // outside one.
        let (mut tip, mut notch) = (0.0_f64, f64::INFINITY);
        for r in 0..h {
            for c in 0..w {
                let x = -1.0 + (c as f64 + 0.5) * 2.0 / w as f64;
                let y = 1.0 - (r as f64 + 0.5) * 2.0 / h as f64;
                let rad = (x * x + y * y).sqrt();
                if image.inside(c, r) {
                    tip = tip.max(rad);
                } else {
                    notch = notch.min(rad);
                }
            }
        }
        assert!(tip > 0.85 && notch < 0.6, "{tip} {notch}");
        assert!((reach.1 - tip).abs() < 0.05 && (reach.0 - notch).abs() < 0.05, "{reach:?}");
    }

    /// The example horn meshes as one closed, genus-0 piece, and its vertices away from the
    /// ball lie on the swept ellipse (`ρ = 1`) within a fraction of a cell.
    #[test]
    fn the_horn_example_is_one_closed_genus_0_piece() {
        let (scene, mesh) = example("horn.toml");
        let r = check(&mesh);
        assert_eq!(r.components.len(), 1);
        let c = &r.components[0];
        assert!(c.closed && c.orientable && c.inconsistent_edges == 0);
        assert_eq!(c.euler, 2, "genus 0");
        assert_eq!(r.outward, Some(true));
        // Vertices beyond the ball's reach, on the horn alone.
        let sweep_only = Scene::parse(
            "[domain]\nmin = [-1, -1, -1]\nmax = [2, 2, 2]\n[skeleton]\nblend = \"sum\"\n\
             [[skeleton.sweep]]\npoints = [[0, 0, 0], [0, 1, 0], [1, 1.2, 0.5], [1.1, 0.4, 1.0]]\n\
             section = \"ellipse\"\nradii = [[0.22, 0.12], [0.16, 0.09], [0.09, 0.06], [0.04, 0.03]]\n\
             normal = [0, 0, 1]\n",
            "h.toml",
        )
        .unwrap();
        let cell = (scene.domain.max - scene.domain.min).max_element() / 96.0;
        let (mut n, mut worst) = (0, 0.0_f64);
        for p in &mesh.positions {
            let p = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            if p.length() > 1.2 {
                // The field is ρ-based: its value is at most about |∇f|·cell/8 off zero.
                let v = sweep_only.field.eval(p);
                let g = sweep_only.field.gradient(p).length();
                assert!(v.abs() / g < 0.1 * cell, "{p}: {v} / {g}");
                worst = worst.max(v.abs() / g / cell);
                n += 1;
            }
        }
        // Texture coordinates (§5.7) of the horn's vertices: in [0, 1], `u` increasing with
        // the nearest curve parameter.
        let sweep = skelform_skeleton::Sweep::new(
            [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.2, 0.5], [1.1, 0.4, 1.0]]
                .map(DVec3::from_array),
            [[0.22, 0.12], [0.16, 0.09], [0.09, 0.06], [0.04, 0.03]],
            1.0,
            skelform_skeleton::SweepSettings {
                initial_normal: Some(DVec3::Z),
                ..Default::default()
            },
        )
        .unwrap();
        let mut tu: Vec<(f64, f64)> = Vec::new();
        for p in &mesh.positions {
            let p = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            let [u, v] = sweep.uv(p);
            assert!((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v), "{p}: {u} {v}");
            tu.push((sweep.nearest_t(p), u));
        }
        tu.sort_by(|a, b| a.0.total_cmp(&b.0));
        assert!(tu.windows(2).all(|w| w[1].1 >= w[0].1), "u not monotone along the curve");
        assert!(tu[0].1 == 0.0 && tu[tu.len() - 1].1 == 1.0, "the caps map to u = 0 and 1");
        println!("horn: {} triangles, {n} horn vertices, worst {worst:.4} cells off", r.faces);
        assert!(n > 500, "{n} vertices checked");
    }
}
