//! Texture coordinates (DIS §5.7) on a meshed sweep (`examples/skeleton/horn.toml`): every
//! vertex has `[u, v]` in `[0, 1]`; on the horn `u` is the arc-length fraction of the nearest
//! curve point (measured here independently, by chords) and grows along the curve, `v` the
//! angle around the section; the same coordinates after a round trip through glb, OBJ and
//! PLY.

use skelform::mesh::io::{Format, WriteOptions, read_mesh_from, write_mesh_to};
use skelform::skeleton::sweep::Sweep;
use skelform::{Mesh, Method, Overrides, Resolution, Scene};

fn example(name: &str) -> String {
    format!("{}/../../examples/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn horn(method: Method) -> (Scene, Mesh) {
    let scene = Scene::load(example("skeleton/horn.toml")).unwrap();
    let o = Overrides {
        resolution: Some(Resolution::Samples(64)),
        method: Some(method),
        ..Overrides::default()
    };
    let mesh = scene.mesh(&o).unwrap().mesh;
    (scene, mesh)
}

/// The arc-length fraction at `t`, by 4000 chords.
fn arc_fraction(s: &Sweep, t: f64) -> f64 {
    let n = 4000;
    let (mut total, mut upto) = (0.0, 0.0);
    for i in 0..n {
        let (a, b) = (i as f64 / n as f64, (i + 1) as f64 / n as f64);
        let d = (s.curve().point(b) - s.curve().point(a)).length();
        total += d;
        if b <= t {
            upto += d;
        } else if a < t {
            upto += d * (t - a) / (b - a);
        }
    }
    upto / total
}

#[test]
fn horn_vertices_have_arc_length_and_angle_coordinates() {
    for method in [Method::Grid, Method::Continuation] {
        let (scene, m) = horn(method);
        assert_eq!(m.uvs.len(), m.positions.len(), "{method:?}");
        assert!(m.validate().is_ok());
        assert!(m.uvs.iter().flatten().all(|c| (0.0..=1.0).contains(c)), "{method:?}");
        let swept = scene.sweeps.as_ref().unwrap();
        let s = &swept.sweeps()[0];
        // Vertices on the horn, away from the ball at its base: (t, u, v, angle).
        let mut along = Vec::new();
        for (p, uv) in m.positions.iter().zip(&m.uvs) {
            let q = skelform::field::DVec3::from_array(p.map(f64::from));
            let l = s.locate(q);
            if (l.rho - 1.0).abs() > 0.05 || l.t < 0.3 || l.s != 0.0 {
                continue;
            }
            let u = f64::from(uv[0]);
            assert!((u - arc_fraction(s, l.t)).abs() < 2e-3, "{method:?} {p:?}: u {u}");
            // The angle of the vertex in the frame at its curve point, from the normal (the
            // section's wide axis) toward the binormal, in the ellipse's own parameter.
            let d = q - l.frame.origin;
            let angle = (d.dot(l.frame.binormal) / l.radii[1])
                .atan2(d.dot(l.frame.normal) / l.radii[0])
                .rem_euclid(std::f64::consts::TAU);
            let v = f64::from(uv[1]);
            let turn = angle / std::f64::consts::TAU;
            let gap = (v - turn).abs();
            assert!(gap.min(1.0 - gap) < 1e-4, "{method:?} {p:?}: v {v}, angle {turn}");
            along.push((l.t, u));
        }
        assert!(along.len() > 500, "{method:?}: {}", along.len());
        // u grows with the curve parameter, so along the curve.
        along.sort_by(|a, b| a.0.total_cmp(&b.0));
        assert!(along.windows(2).all(|w| w[1].1 >= w[0].1 - 1e-6), "{method:?}");
        assert!(along.last().unwrap().1 > 0.9 && along[0].1 < 0.45, "{method:?}");
        // v covers the whole turn.
        let vs: Vec<f32> = m.uvs.iter().map(|uv| uv[1]).collect();
        for quarter in 0..4 {
            let lo = quarter as f32 * 0.25;
            assert!(vs.iter().any(|&v| v >= lo && v < lo + 0.25), "{method:?} {quarter}");
        }
    }
}

#[test]
fn texture_coordinates_survive_glb_obj_and_ply() {
    let (_, m) = horn(Method::Grid);
    for format in [Format::Glb, Format::Obj, Format::Ply] {
        let mut bytes = Vec::new();
        write_mesh_to(&mut bytes, &m, format, &WriteOptions::default()).unwrap();
        let back = read_mesh_from(&bytes, format).unwrap();
        // glb stores the vertices in order of first use: compare vertex by vertex, by
        // position.
        let uv_at: std::collections::HashMap<[u32; 3], [f32; 2]> = m
            .positions
            .iter()
            .zip(&m.uvs)
            .map(|(p, uv)| (p.map(|c| (c + 0.0).to_bits()), *uv))
            .collect();
        assert_eq!(back.uvs.len(), back.positions.len(), "{format:?}");
        assert!(back.positions.len() >= m.positions.len() * 9 / 10, "{format:?}");
        for (p, uv) in back.positions.iter().zip(&back.uvs) {
            assert_eq!(uv_at.get(&p.map(|c| (c + 0.0).to_bits())), Some(uv), "{format:?} {p:?}");
        }
        if format != Format::Glb {
            assert_eq!(back.uvs, m.uvs, "{format:?}");
        }
    }
    let mut text = Vec::new();
    write_mesh_to(&mut text, &m, Format::Obj, &WriteOptions::default()).unwrap();
    let text = String::from_utf8(text).unwrap();
    assert!(text.lines().any(|l| l.starts_with("vt ")));
    let face = text.lines().find(|l| l.starts_with("f ")).unwrap();
    let corner = face.split_whitespace().nth(1).unwrap();
    let parts: Vec<&str> = corner.split('/').collect();
    assert!(parts.len() == 3 && parts[0] == parts[1] && parts[1] == parts[2], "{face}");
}

#[test]
fn scenes_without_sweeps_have_no_texture_coordinates() {
    let scene = Scene::load(example("skeleton/colours.toml")).unwrap();
    let o = Overrides { resolution: Some(Resolution::Samples(32)), ..Overrides::default() };
    let m = scene.mesh(&o).unwrap().mesh;
    assert!(!m.triangles.is_empty() && m.uvs.is_empty());
}
