//! The library's front door as a user meets it: load, override, mesh, read the statistics.

use std::ops::ControlFlow;

use skelform::mesh::check::check;
use skelform::{Control, DVec3, Method, Overrides, Resolution, Scene, Stats, Threads};

fn example(name: &str) -> String {
    format!("{}/../../examples/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn coarse() -> Overrides {
    Overrides { resolution: Some(Resolution::Samples(24)), ..Overrides::default() }
}

#[test]
fn every_field_method_meshes_the_torus_as_one_closed_genus_one_surface() {
    let scene = Scene::load(example("torus.toml")).unwrap();
    for method in [Method::Grid, Method::Continuation, Method::Tetra, Method::Healed] {
        let m = scene.mesh(&Overrides { method: Some(method), ..coarse() }).unwrap();
        assert_eq!(m.method, method);
        let r = check(&m.mesh);
        assert!(r.is_closed_manifold(), "{method:?}");
        assert_eq!(r.components.len(), 1, "{method:?}");
        assert_eq!(r.components[0].genus, Some(1), "{method:?}");
        assert!(m.stats.evaluations() > 0);
        assert!(m.stats.warnings().is_empty(), "{method:?}: {:?}", m.stats.warnings());
        let text = m.stats.to_string();
        assert!(text.contains("triangles"), "{text}");
    }
}

#[test]
fn parsed_text_and_loaded_file_give_the_same_mesh() {
    let text = std::fs::read_to_string(example("sphere.toml")).unwrap();
    let a = Scene::parse(&text, "<string>").unwrap().mesh(&coarse()).unwrap();
    let b = Scene::load(example("sphere.toml")).unwrap().mesh(&coarse()).unwrap();
    assert_eq!(a.mesh.positions, b.mesh.positions);
    assert_eq!(a.mesh.triangles, b.mesh.triangles);
}

#[test]
fn the_mesh_is_the_same_on_any_number_of_threads() {
    let scene = Scene::load(example("gyroid.toml")).unwrap();
    let one = scene.mesh(&Overrides { threads: Some(Threads::Count(1)), ..coarse() }).unwrap();
    let two = scene.mesh(&Overrides { threads: Some(Threads::Count(2)), ..coarse() }).unwrap();
    assert_eq!(one.mesh.positions, two.mesh.positions);
    assert_eq!(one.mesh.triangles, two.mesh.triangles);
}

/// The hand (85 skeletal elements, a seed each, one component) with the continuation
/// method, on 1, 2 and 4 threads of the caller's pool: the same mesh, byte for byte.
#[test]
fn the_hand_by_continuation_is_the_same_on_1_2_and_4_threads() {
    let scene = Scene::load(example("skeleton/hand.toml")).unwrap();
    let overrides = Overrides {
        method: Some(Method::Continuation),
        resolution: Some(Resolution::Samples(64)),
        ..Overrides::default()
    };
    let go = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| scene.mesh(&overrides).unwrap().mesh)
    };
    let one = go(1);
    assert!(one.triangle_count() > 1000);
    for threads in [2, 4] {
        let m = go(threads);
        assert_eq!(m.positions, one.positions, "{threads} threads");
        assert_eq!(m.triangles, one.triangles, "{threads} threads");
        assert_eq!(m.normals, one.normals, "{threads} threads");
    }
}

/// Issue 20's speed goal for continuation, with the accuracy it must keep: the hand at a
/// 128-samples cell takes at most 3.25 field evaluations per output vertex (7.02 before
/// corner gradients and the lattice walk from the seeds; the breakdown below is what each
/// part is allowed), and every vertex lies within half the root tolerance of the surface
/// (|f| / |∇f|), as regula falsi's vertices did (1.05e-6 at most, of 1.8e-6).
#[test]
fn the_hand_by_continuation_is_cheap_and_on_the_surface() {
    let scene = Scene::load(example("skeleton/hand.toml")).unwrap();
    let overrides = Overrides {
        method: Some(Method::Continuation),
        resolution: Some(Resolution::Samples(128)),
        ..Overrides::default()
    };
    let m = scene.mesh(&overrides).unwrap();
    let Stats::Continuation(s) = &m.stats else { panic!("continuation's statistics") };
    let n = s.vertices as f64;
    assert!(n > 15_000.0);
    let per = |e: u64| e as f64 / n;
    let report = format!(
        "corners {:.2}, search {:.2}, roots {:.2}, normals {:.2} per vertex",
        per(s.corner_evaluations),
        per(s.search_evaluations),
        per(s.refine_evaluations),
        per(s.normal_evaluations)
    );
    assert!(per(s.evaluations()) <= 3.25, "{report}");
    assert!(per(s.search_evaluations) < 0.2, "{report}");
    assert!(per(s.refine_evaluations) < 1.25, "{report}");
    assert!(per(s.normal_evaluations) < 0.01, "{report}");
    let tolerance = 0.5 * 1e-4 * s.cell;
    let d = skelform::surface_distance(scene.description().field.as_ref(), &m.mesh, tolerance);
    assert_eq!((d.over, d.unmeasured), (0, 0), "{d:?}");
    assert!(d.mean < 0.05 * tolerance, "{d:?}");
    assert_eq!(m.mesh.normals.len(), m.mesh.positions.len());
    let r = check(&m.mesh);
    assert!(r.is_closed_manifold());
    assert_eq!(r.components.len(), 1);
    assert_eq!(r.components[0].genus, Some(0));
}

#[test]
fn a_pose_override_rebuilds_the_skeleton() {
    let scene = Scene::load(example("skeleton/hand.toml")).unwrap();
    let rest = scene.mesh(&coarse()).unwrap();
    let grip = scene.mesh(&Overrides { pose: Some("grip".into()), ..coarse() }).unwrap();
    assert_ne!(rest.mesh.positions, grip.mesh.positions);
    let loaded = Scene::load_with(
        example("skeleton/hand.toml"),
        &skelform::LoadOptions { pose: Some("grip".into()), ..Default::default() },
    )
    .unwrap()
    .mesh(&coarse())
    .unwrap();
    assert_eq!(grip.mesh.positions, loaded.mesh.positions);
    let e = scene.mesh(&Overrides { pose: Some("wave".into()), ..coarse() }).unwrap_err();
    assert!(e.is_input() && e.to_string().contains("grip"), "{e}");
}

#[test]
fn bad_overrides_are_the_inputs_fault() {
    let scene = Scene::load(example("sphere.toml")).unwrap();
    for o in [
        Overrides { resolution: Some(Resolution::Samples(1)), ..Overrides::default() },
        Overrides { resolution: Some(Resolution::Cell(-1.0)), ..Overrides::default() },
        Overrides { tolerance: Some(2.0), ..coarse() },
        Overrides { method: Some(Method::NonManifold), ..coarse() },
        Overrides { max_memory: Some(1 << 10), ..coarse() },
        Overrides {
            seeds: Some(vec![DVec3::new(9.0, 0.0, 0.0)]),
            method: Some(Method::Continuation),
            ..coarse()
        },
    ] {
        let e = scene.mesh(&o).unwrap_err();
        assert!(e.is_input(), "{e}");
        assert!(e.to_string().starts_with(&scene.origin), "{e}");
    }
}

#[test]
fn a_cancelled_run_says_so() {
    let scene = Scene::load(example("gyroid.toml")).unwrap();
    let control = Control::with_callback(|_| ControlFlow::Break(()));
    let e = scene.mesh(&Overrides { control, ..coarse() }).unwrap_err();
    assert!(e.is_cancelled(), "{e}");
    assert!(!e.is_input());
}

#[test]
fn statistics_serialize_with_their_method_specific_fields() {
    let grid = Scene::load(example("sphere.toml")).unwrap().mesh(&coarse()).unwrap();
    let j = serde_json::to_value(&grid.stats).unwrap();
    assert!(matches!(grid.stats, Stats::Grid(_)));
    assert_eq!(j["triangles"].as_u64().unwrap() as usize, grid.mesh.triangle_count());
    assert!(j["sampling"].as_f64().unwrap() >= 0.0, "durations in seconds: {j}");
    let regions = Scene::load(example("nonmanifold/saucer-and-square.toml")).unwrap();
    let nm = regions.mesh(&Overrides::default()).unwrap();
    let j = serde_json::to_value(&nm.stats).unwrap();
    assert_eq!(j["surfaces"].as_array().unwrap().len(), 3, "{j}");
    assert_eq!(j["surfaces"][0]["pair"], serde_json::json!([1, 2]));
    assert!(!nm.mesh.labels.is_empty());
}

#[test]
fn an_empty_domain_is_explained() {
    let scene = Scene::parse(
        "[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\n[field]\nformula = \"x^2 + y^2 + z^2 + 1\"\n",
        "<empty>",
    ).unwrap();
    let m = scene.mesh(&coarse()).unwrap();
    assert!(m.mesh.is_empty());
    let why = m.no_surface(&scene).unwrap();
    assert!(why.starts_with("<empty>: no surface") && why.contains("outside"), "{why}");
}

#[test]
fn the_lattice_tells_each_methods_up_front_need_and_a_run_is_refused_by_it() {
    use skelform::MemoryNeed;
    let scene = Scene::load(example("torus.toml")).unwrap();
    let at = |method, resolution, seeds: Option<Vec<DVec3>>| {
        let o = Overrides {
            method: Some(method),
            resolution: Some(Resolution::Samples(resolution)),
            seeds,
            ..Overrides::default()
        };
        (scene.lattice(&o).unwrap(), o)
    };
    let (grid, _) = at(Method::Grid, 64, None);
    assert!(matches!(grid.need, MemoryNeed::Lattice { streamed: false, .. }), "{grid:?}");
    assert_eq!(grid.method, Method::Grid);
    // A volume past the streaming threshold is streamed by the grid method, never by healed,
    // which looks back at the whole volume.
    let (streamed, _) = at(Method::Grid, 600, None);
    assert!(streamed.streamed(), "{streamed:?}");
    let (healed, _) = at(Method::Healed, 600, None);
    assert!(!healed.streamed() && healed.memory() > streamed.memory(), "{healed:?}");
    // Continuation without seeds searches the domain; with seeds nothing is known up front.
    let (search, o) = at(Method::Continuation, 256, Some(Vec::new()));
    assert!(matches!(search.need, MemoryNeed::Search(b) if b > 0), "{search:?}");
    let (seeded, _) = at(Method::Tetra, 256, Some(vec![DVec3::ZERO]));
    assert_eq!(seeded.need, MemoryNeed::Surface);
    assert_eq!(seeded.memory(), 0);
    // What the lattice says is what a run is refused by, before any work.
    let limit = search.memory() - 1;
    let err = scene.mesh(&Overrides { max_memory: Some(limit), ..o }).unwrap_err();
    assert!(err.is_input(), "{err}");
    assert!(err.to_string().contains("over the limit"), "{err}");
    // The non-manifold full-grid mode counts every cube.
    let foam = Scene::load(example("nonmanifold/sphere-and-square.toml")).unwrap();
    let full = foam.lattice(&Overrides::default()).unwrap();
    assert!(matches!(full.need, MemoryNeed::FullGrid(b) if b > 1 << 20), "{full:?}");
}

/// Issue 18: on every non-manifold example, fewer than 1% of face vertices fall back to the
/// mean of the face's crossings (the tee in its square, whose sheet lies on a lattice
/// plane, had half of them: saw-toothed borders), and no faces coincide or fold.
#[test]
fn nonmanifold_examples_place_their_face_vertices_by_following_the_contours() {
    let dir = format!("{}/../../examples/nonmanifold", env!("CARGO_MANIFEST_DIR"));
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    names.sort();
    assert!(names.len() >= 10, "{names:?}");
    for path in names {
        let m = Scene::load(&path).unwrap().mesh(&Overrides::default()).unwrap();
        let Stats::NonManifold(s) = &m.stats else { panic!("{path:?}: not non-manifold") };
        assert!(s.face_vertices > 0, "{path:?}");
        assert!(
            s.face_vertex_fallbacks * 100 < s.face_vertices,
            "{path:?}: {} of {} face vertices fell back",
            s.face_vertex_fallbacks,
            s.face_vertices
        );
        let r = check(&m.mesh);
        assert_eq!(r.coincident_faces, 0, "{path:?}");
        assert_eq!(r.folded_edges, 0, "{path:?}");
    }
}
