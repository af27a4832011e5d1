//! Element colours on a meshed scene (`examples/skeleton/colours.toml`): red vertices over
//! the red segment, blue over the blue one, a blend between; the same colours after a
//! round trip through PLY and glb; every method colours, the posed hand is skin.

use skelform::mesh::io::{Format, WriteOptions, read_glb, read_ply, write_mesh_to};
use skelform::{Mesh, Method, Overrides, Resolution, Scene};

fn example(name: &str) -> String {
    format!("{}/../../examples/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn meshed(method: Method) -> Mesh {
    let scene = Scene::load(example("skeleton/colours.toml")).unwrap();
    let o = Overrides {
        resolution: Some(Resolution::Samples(64)),
        method: Some(method),
        ..Overrides::default()
    };
    scene.mesh(&o).unwrap().mesh
}

const RED: [f32; 3] = [0.85, 0.1, 0.1];
const BLUE: [f32; 3] = [0.1, 0.2, 0.85];

fn close(a: [f32; 3], b: [f32; 3], tol: f32) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() <= tol)
}

#[test]
fn red_near_red_blue_near_blue_blended_between() {
    for method in [Method::Grid, Method::Continuation] {
        let m = meshed(method);
        assert_eq!(m.colors.len(), m.positions.len(), "{method:?}");
        let (mut reds, mut blues, mut between) = (0, 0, 0);
        for (p, c) in m.positions.iter().zip(&m.colors) {
            if p[0] < -0.6 {
                // Over the red segment, away from the blend: red.
                assert!(close(*c, RED, 0.01), "{method:?}: {p:?} {c:?}");
                reds += 1;
            } else if p[0] > 0.6 {
                assert!(close(*c, BLUE, 0.01), "{method:?}: {p:?} {c:?}");
                blues += 1;
            } else if p[0].abs() < 0.05 && p[1] < -0.1 {
                // Under the gap, far from the yellow point: half red, half blue.
                let mid = [0, 1, 2].map(|k| 0.5 * (RED[k] + BLUE[k]));
                assert!(close(*c, mid, 0.1), "{method:?}: {p:?} {c:?}");
                between += 1;
            }
        }
        assert!(reds > 300 && blues > 300 && between >= 2, "{reds} {blues} {between}");
        // Redness falls from left to right along the bottom of the tube.
        let mut bottom: Vec<(f32, f32)> = m
            .positions
            .iter()
            .zip(&m.colors)
            .filter(|(p, _)| p[1] < -0.15 && p[2].abs() < 0.05)
            .map(|(p, c)| (p[0], c[0]))
            .collect();
        bottom.sort_by(|a, b| a.0.total_cmp(&b.0));
        assert!(bottom.windows(2).all(|w| w[1].1 <= w[0].1 + 0.01), "{method:?}");
    }
}

#[test]
fn colours_survive_ply_and_glb() {
    let m = meshed(Method::Grid);
    let mut ply = Vec::new();
    write_mesh_to(&mut ply, &m, Format::Ply, &WriteOptions::default()).unwrap();
    let back = read_ply(&ply[..]).unwrap();
    assert!(back.positions == m.positions);
    for (a, b) in back.colors.iter().zip(&m.colors) {
        assert!(close(*a, *b, 0.5 / 255.0 + 1e-6), "{a:?} {b:?}");
    }
    let mut glb = Vec::new();
    write_mesh_to(&mut glb, &m, Format::Glb, &WriteOptions::default()).unwrap();
    // The glb numbers vertices by first use: match them by position.
    let back = read_glb(&glb).unwrap();
    assert_eq!(back.colors.len(), m.positions.len());
    let at: std::collections::HashMap<[u32; 3], usize> =
        m.positions.iter().enumerate().map(|(i, p)| (p.map(f32::to_bits), i)).collect();
    for (p, a) in back.positions.iter().zip(&back.colors) {
        let b = m.colors[at[&p.map(f32::to_bits)]];
        assert!(close(*a, b, 1e-5), "{a:?} {b:?}");
    }
}

#[test]
fn the_hand_is_skin_with_bluish_veins_and_nails() {
    let scene = Scene::load(example("skeleton/hand.toml")).unwrap();
    let o = Overrides {
        resolution: Some(Resolution::Samples(48)),
        pose: Some("grip".into()),
        ..Overrides::default()
    };
    let m = scene.mesh(&o).unwrap().mesh;
    assert_eq!(m.colors.len(), m.positions.len());
    let skin = [0.88, 0.67, 0.56];
    let n_skin = m.colors.iter().filter(|c| close(**c, skin, 1e-3)).count();
    // Most of the hand is skin; the veins tint some of the back bluish (less red, more
    // blue than skin), never beyond the vein colour itself.
    assert!(n_skin * 10 > m.colors.len() * 8, "{n_skin} of {}", m.colors.len());
    let tinted = m.colors.iter().filter(|c| c[2] > skin[2] + 0.02 && c[0] < skin[0]).count();
    assert!(tinted > 0);
    // The nails are nail-coloured (a sharp union: no blending into the skin).
    let nail = [0.96, 0.83, 0.8];
    let n_nail = m.colors.iter().filter(|c| close(**c, nail, 1e-3)).count();
    assert!(n_nail > 0 && n_nail * 20 < m.colors.len(), "{n_nail} nail of {}", m.colors.len());
    // Every colour is a blend of the skin's, the veins' and the nails'.
    let vein = [0.62, 0.58, 0.72];
    for c in &m.colors {
        for i in 0..3 {
            let (lo, hi) = (skin[i].min(vein[i]).min(nail[i]), skin[i].max(vein[i]).max(nail[i]));
            assert!(c[i] >= lo - 1e-4 && c[i] <= hi + 1e-4, "{c:?}");
        }
    }
}

#[test]
fn the_leaf_carries_its_tertiary_venation_in_vertex_colours_the_ply_and_the_glb() {
    // examples/nonmanifold/leaf.toml has `texture = true`: every vertex of the labelled
    // non-manifold mesh has a colour of the texture, the blade mostly blade green with
    // lighter tertiary lines, the veins pale; the colours survive the PLY, and the glb
    // carries the texture image and texture coordinates instead.
    let scene = Scene::load(example("nonmanifold/leaf.toml")).unwrap();
    let o = Overrides { resolution: Some(Resolution::Cell(0.04)), ..Overrides::default() };
    let m = scene.mesh(&o).unwrap().mesh;
    assert_eq!(m.colors.len(), m.positions.len());
    assert_eq!(m.labels.len(), m.triangles.len());
    let p = skelform::leaf::TextureParams::default();
    let (mut blade, mut tertiary, mut vein) = (0, 0, 0);
    let on_blade: std::collections::BTreeSet<u32> = m
        .triangles
        .iter()
        .zip(&m.labels)
        .filter(|(_, l)| (l.0, l.1) == (2, 3))
        .flat_map(|(t, _)| *t)
        .collect();
    for &v in &on_blade {
        let c = m.colors[v as usize];
        if close(c, p.blade, 1e-6) {
            blade += 1;
        } else if close(c, p.vein, 1e-6) {
            vein += 1;
        } else {
            // Near a tertiary line: between blade green and the line's lighter colour.
            assert!((0..3).all(|k| c[k] > p.blade[k] && c[k] <= p.vein[k] + 1e-6), "{c:?}");
            tertiary += 1;
        }
    }
    let n = on_blade.len();
    eprintln!(
        "{n} blade vertices: {blade} blade green, {tertiary} on tertiary lines, {vein} on veins"
    );
    assert!(blade * 3 > n, "{blade} of {n} plain blade");
    assert!(tertiary * 20 > n && tertiary < blade, "{tertiary} of {n} near tertiary lines");
    // The same colours on another run (the texture is seeded, colouring is per vertex).
    let again = scene.mesh(&o).unwrap().mesh;
    assert_eq!(again.colors, m.colors);
    let mut ply = Vec::new();
    write_mesh_to(&mut ply, &m, Format::Ply, &WriteOptions::default()).unwrap();
    let back = read_ply(&ply[..]).unwrap();
    assert_eq!(back.colors.len(), back.positions.len());
    for (a, b) in back.colors.iter().zip(&m.colors) {
        assert!(close(*a, *b, 1e-2), "{a:?} {b:?}");
    }
    let mut glb = Vec::new();
    write_mesh_to(&mut glb, &m, Format::Glb, &WriteOptions::default()).unwrap();
    let back = read_glb(&glb).unwrap();
    assert!(back.colors.is_empty());
    assert_eq!(back.texture, m.texture);
    assert!(m.texture.is_some());
    let at: std::collections::HashMap<[u32; 3], usize> =
        m.positions.iter().enumerate().map(|(i, p)| (p.map(f32::to_bits), i)).collect();
    for (q, uv) in back.positions.iter().zip(&back.uvs) {
        assert_eq!(*uv, m.uvs[at[&q.map(f32::to_bits)]]);
    }
}

/// Continuation with root finding colours the vertices in its own evaluations, a Newton step
/// from each vertex: the colours are the skeleton's at the vertices themselves (what painting
/// gave) to a thousandth, on the hand (several cliques, nails of another colour) and the
/// colours example; with colours off the mesh has none, and the same positions come out.
#[test]
fn continuation_colours_from_root_finding_are_the_painted_colours() {
    for (name, samples) in [("skeleton/hand.toml", 48), ("skeleton/colours.toml", 64)] {
        let scene = Scene::load(example(name)).unwrap();
        let skeleton = scene.skeleton.clone().expect("a skeleton");
        let o = Overrides {
            resolution: Some(Resolution::Samples(samples)),
            method: Some(Method::Continuation),
            ..Overrides::default()
        };
        let m = &scene.mesh(&o).unwrap().mesh;
        assert_eq!(m.colors.len(), m.positions.len(), "{name}");
        let points: Vec<skelform::DVec3> =
            m.positions.iter().map(|p| skelform::DVec3::from_array(p.map(f64::from))).collect();
        let painted = skeleton.colors(&points).unwrap();
        let mut mixed = 0;
        for (c, want) in m.colors.iter().zip(&painted) {
            assert!(close(*c, *want, 1e-3), "{name}: {c:?} against {want:?}");
            mixed += usize::from(c != &m.colors[0]);
        }
        assert!(mixed > 0, "{name}: one colour everywhere");
        let off = scene.mesh(&Overrides { colors: Some(false), ..o.clone() }).unwrap().mesh;
        assert!(off.colors.is_empty(), "{name}");
        assert_eq!(off.positions, m.positions, "{name}");
    }
}
