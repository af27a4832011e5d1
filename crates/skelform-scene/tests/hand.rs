//! The hand of DIS chapter 6 (`examples/skeleton/hand.toml`): the element counts the
//! dissertation gives, the chapter-2 finger parameters as joint angles, and, in every pose,
//! one closed, manifold, outward surface whose fingers stay apart.

use std::path::{Path, PathBuf};

use glam::DVec3;
use skelform_field::Field;
use skelform_mesh::check::check;
use skelform_polygonize::LatticeOptions;
use skelform_polygonize::grid::{Options, Resolution, polygonize};
use skelform_scene::{LoadOptions, Scene};

const FINGERS: [&str; 5] = ["thumb", "index", "middle", "ring", "pinkie"];

/// The dissertation's finger specification (DIS §2.7): θ, φ, grip2, grip3 (degrees), the
/// three bone lengths and the radius (inches).
const SPEC: [[f64; 8]; 5] = [
    [30.0, 20.0, 0.0, 30.0, 0.8, 0.8, 0.45, 0.1125],
    [10.0, 15.0, 30.0, 10.0, 0.75, 0.6, 0.25, 0.0875],
    [0.0, 15.0, 30.0, 10.0, 0.9, 0.7, 0.25, 0.0875],
    [-10.0, 15.0, 25.0, 5.0, 0.85, 0.6, 0.35, 0.0875],
    [-25.0, 15.0, 25.0, 5.0, 0.65, 0.45, 0.3, 0.08],
];

fn hand_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/skeleton/hand.toml")
}

fn hand(pose: &str) -> Scene {
    let options = LoadOptions { pose: Some(pose.to_string()), ..Default::default() };
    Scene::load_with(&hand_path(), &options).unwrap_or_else(|e| panic!("{e}"))
}

fn toml_file() -> toml::Table {
    std::fs::read_to_string(hand_path()).unwrap().parse().unwrap()
}

fn tables<'a>(t: &'a toml::Table, kind: &str) -> Vec<&'a toml::Table> {
    t["skeleton"]
        .get(kind)
        .and_then(|v| v.as_array())
        .map(|a| a.iter().map(|x| x.as_table().unwrap()).collect())
        .unwrap_or_default()
}

fn group(t: &toml::Table) -> &str {
    t.get("group").and_then(|g| g.as_str()).unwrap_or("default")
}

fn number(v: &toml::Value) -> f64 {
    v.as_float().or_else(|| v.as_integer().map(|i| i as f64)).unwrap()
}

#[test]
fn the_hand_has_the_dissertations_85_elements() {
    let t = toml_file();
    let triangles = tables(&t, "triangle");
    let palm = triangles.iter().filter(|x| group(x) == "palm").count();
    let fingers = triangles.iter().filter(|x| FINGERS.contains(&group(x))).count();
    assert_eq!((palm, fingers, triangles.len()), (15, 48, 63));
    let chains = |g: &str| -> Vec<usize> {
        tables(&t, "polyline")
            .iter()
            .filter(|x| group(x) == g)
            .map(|x| x["points"].as_array().unwrap().len() - 1)
            .collect()
    };
    let tendons = chains("tendons");
    assert_eq!((tendons.len(), tendons.iter().sum::<usize>()), (5, 10), "tendons {tendons:?}");
    let veins = chains("veins");
    assert_eq!((veins.len(), veins.iter().sum::<usize>()), (2, 11), "veins {veins:?}");
    let muscle = tables(&t, "segment");
    assert_eq!(muscle.len(), 1);
    assert_eq!(group(muscle[0]), "muscle");
    assert!(tables(&t, "point").is_empty() && tables(&t, "polygon").is_empty());
    assert!(tables(&t, "curve").is_empty());
    // And the field has them all.
    assert_eq!(hand("rest").skeleton.unwrap().element_count(), 85);
}

#[test]
fn the_joints_carry_the_chapter_2_finger_parameters() {
    let t = toml_file();
    let joints = tables(&t, "joint");
    let joint = |name: &str| *joints.iter().find(|j| j["name"].as_str() == Some(name)).unwrap();
    let angles = |j: &toml::Table| -> Vec<f64> {
        match &j["angles"] {
            toml::Value::Array(a) => a.iter().map(number).collect(),
            v => vec![number(v)],
        }
    };
    for (finger, spec) in FINGERS.iter().zip(SPEC) {
        let [theta, phi, grip2, grip3, l1, l2, l3, r] = spec;
        let j1 = joint(&format!("{finger}1"));
        let j2 = joint(&format!("{finger}2"));
        let j3 = joint(&format!("{finger}3"));
        assert_eq!(angles(j1), [theta, phi], "{finger}");
        assert_eq!(angles(j2), [grip2], "{finger}");
        assert_eq!(angles(j3), [grip3], "{finger}");
        let at = |j: &toml::Table| -> Vec<f64> {
            j["at"].as_array().unwrap().iter().map(number).collect()
        };
        assert_eq!(at(j2), [l1, 0.0, 0.0], "{finger}: length 1");
        assert_eq!(at(j3), [l2, 0.0, 0.0], "{finger}: length 2");
        // The finger's triangles: its radius, and the last bone as long as length 3.
        let tris: Vec<&toml::Table> =
            tables(&t, "triangle").into_iter().filter(|x| group(x) == *finger).collect();
        assert!(tris.iter().all(|x| number(&x["radius"]) == r), "{finger}: radius");
        let tip = tris
            .iter()
            .filter(|x| x["joint"].as_str() == Some(&format!("{finger}3")))
            .flat_map(|x| x["vertices"].as_array().unwrap())
            .map(|v| number(&v.as_array().unwrap()[0]))
            .fold(0.0, f64::max);
        assert_eq!(tip, l3, "{finger}: length 3");
    }
}

/// Where a finger's tip and the middle of its second bone are in a pose.
fn finger_points(scene: &Scene, finger: usize) -> (DVec3, DVec3) {
    let art = scene.articulation.as_ref().unwrap();
    let frame = |name: String| art.frames[art.joints.iter().position(|j| *j == name).unwrap()];
    let name = FINGERS[finger];
    let [.., l2, l3, _] = SPEC[finger];
    let tip = frame(format!("{name}3")).transform_point3(DVec3::new(l3, 0.0, 0.0));
    let mid = frame(format!("{name}2")).transform_point3(DVec3::new(0.5 * l2, 0.0, 0.0));
    (tip, mid)
}

/// The longest run of points outside the surface on the segment from `a` to `b`, as a
/// length (0 when the segment is inside all the way).
fn gap(field: &dyn Field, a: DVec3, b: DVec3) -> f64 {
    let n = 400;
    let (mut run, mut best) = (0, 0);
    for i in 0..=n {
        let p = a.lerp(b, i as f64 / n as f64);
        if field.eval(p) > 0.0 {
            run += 1;
            best = best.max(run);
        } else {
            run = 0;
        }
    }
    best as f64 / n as f64 * (b - a).length()
}

#[test]
fn the_rest_pose_is_one_closed_outward_surface_with_separate_fingers() {
    one_closed_surface_with_separate_fingers("rest");
}

#[test]
fn the_open_hand_is_one_closed_outward_surface_with_separate_fingers() {
    one_closed_surface_with_separate_fingers("open");
}

#[test]
fn the_grip_is_one_closed_outward_surface_with_separate_fingers() {
    one_closed_surface_with_separate_fingers("grip");
}

fn one_closed_surface_with_separate_fingers(pose: &str) {
    let scene = hand(pose);
    assert_eq!(scene.articulation.as_ref().unwrap().pose, pose);
    // A coarse grid (cell 0.035 in, about a fifth of a finger's thickness) keeps the
    // test fast and still resolves the gaps between the fingers.
    let lattice = LatticeOptions {
        domain: scene.domain,
        resolution: Resolution::Cell(0.035),
        ..Default::default()
    };
    let opts = Options { lattice, ..Default::default() };
    let (mesh, _) = polygonize(&*scene.field, &opts).unwrap();
    let r = check(&mesh);
    println!("{pose}: {} triangles, {} components", r.faces, r.components.len());
    assert_eq!(r.components.len(), 1, "{pose}: one piece");
    let c = &r.components[0];
    assert!(c.is_closed_manifold() && c.consistently_oriented, "{pose}");
    assert_eq!(r.outward, Some(true), "{pose}");
    // Genus 0: no finger touches another (or the palm) anywhere but at its base, which
    // would close a loop.
    assert_eq!(c.genus, Some(0), "{pose}");
    // Between neighbouring fingertips, and between the middles of neighbouring second
    // bones, there is open space.
    for f in 0..4 {
        let (tip_a, mid_a) = finger_points(&scene, f);
        let (tip_b, mid_b) = finger_points(&scene, f + 1);
        let (g_tip, g_mid) = (gap(&*scene.field, tip_a, tip_b), gap(&*scene.field, mid_a, mid_b));
        println!(
            "{pose}: {} | {}: gap {g_tip:.3} at the tips, {g_mid:.3} mid-finger",
            FINGERS[f],
            FINGERS[f + 1]
        );
        assert!(
            g_tip > 0.04 && g_mid > 0.04,
            "{pose}: {} and {} fused",
            FINGERS[f],
            FINGERS[f + 1]
        );
        // The tips are on the hand: just inside each fingertip the field is negative.
        for (finger, tip) in [(f, tip_a), (f + 1, tip_b)] {
            let name = format!("{}3", FINGERS[finger]);
            let art = scene.articulation.as_ref().unwrap();
            let frame = art.frames[art.joints.iter().position(|j| *j == name).unwrap()];
            let inside = frame.transform_point3(DVec3::new(SPEC[finger][6] - 0.03, 0.0, 0.0));
            assert!(scene.field.eval(inside) < 0.0, "{pose}: {name} tip {tip} not on the surface");
        }
    }
}

#[test]
fn gripping_brings_the_fingertips_to_the_palm_and_keeps_the_bones() {
    let palm_centre = DVec3::new(0.0, 0.6, 0.0);
    let (open, grip, rest) = (hand("open"), hand("grip"), hand("rest"));
    for f in 0..5 {
        let (d_open, d_grip, d_rest) = (
            (finger_points(&open, f).0 - palm_centre).length(),
            (finger_points(&grip, f).0 - palm_centre).length(),
            (finger_points(&rest, f).0 - palm_centre).length(),
        );
        println!(
            "{}: tip to palm centre {d_open:.3} open, {d_rest:.3} rest, {d_grip:.3} grip",
            FINGERS[f]
        );
        assert!(d_grip < d_rest && d_rest <= d_open + 1e-9, "{}", FINGERS[f]);
        if f > 0 {
            assert!(d_grip < 0.75 * d_open, "{}: the grip closes the hand", FINGERS[f]);
        }
        // Rotation, not interpolation: every bone keeps its length in every pose.
        for scene in [&open, &grip, &rest] {
            let art = scene.articulation.as_ref().unwrap();
            let at = |n: String| art.frames[art.joints.iter().position(|j| *j == n).unwrap()];
            let name = FINGERS[f];
            let (j1, j2, j3) =
                (at(format!("{name}1")), at(format!("{name}2")), at(format!("{name}3")));
            let tip = finger_points(scene, f).0;
            let lengths = [
                (j2.translation - j1.translation).length(),
                (j3.translation - j2.translation).length(),
                (tip - j3.translation).length(),
            ];
            for (l, want) in lengths.iter().zip(&SPEC[f][4..7]) {
                assert!((l - want).abs() < 1e-12, "{name}: {l} vs {want}");
            }
        }
    }
}
