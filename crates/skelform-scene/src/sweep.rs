//! `[[skeleton.sweep]]`: generalized cylinders (DIS §5.3–5.5), parsed and validated into
//! [`skelform_skeleton::Sweep`]s. Kept apart from `skeleton.rs` because a sweep is not an
//! element of the [`skelform_skeleton::Skeleton`]: it is added to the skeleton's field by
//! [`skelform_skeleton::SweptField`].

use serde::Deserialize;
use skelform_field::DVec3;
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
    /// `"circle"` (default) or `"ellipse"`.
    section: Option<Spanned<String>>,
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

/// The sweeps of a skeleton section.
pub(crate) fn build(specs: &[SweepSpec], at: At) -> Result<Vec<Sweep>, SceneError> {
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
        let ellipse = match &sp.section {
            None => false,
            Some(s) => match s.get_ref().as_str() {
                "circle" => false,
                "ellipse" => true,
                other => {
                    return Err(at(
                        s.span().start,
                        format!("unknown section '{other}'; expected circle or ellipse"),
                    ));
                }
            },
        };
        let radii: [[f64; 2]; 4] = match (ellipse, &sp.radius, &sp.radii) {
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
        out.push(sweep);
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
        assert!(m.contains("circle or ellipse"), "{m}");
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

    /// The example horn meshes as one closed, genus-0 piece, and its vertices away from the
    /// ball lie on the swept ellipse (`ρ = 1`) within a fraction of a cell.
    #[test]
    fn the_horn_example_is_one_closed_genus_0_piece() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples/skeleton/horn.toml");
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let lattice = LatticeOptions {
            domain: scene.domain,
            resolution: scene.resolution,
            ..Default::default()
        };
        let (mesh, _) =
            polygonize(&*scene.field, &Options { lattice, ..Default::default() }).unwrap();
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
