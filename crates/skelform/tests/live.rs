//! `Live`: incremental re-meshing after edits gives the fresh run's mesh, bit for bit, and
//! progressive meshing stops when cancelled.

use proptest::prelude::*;
use skelform::{Control, Live, Overrides, Resolution, Scene};

/// A small articulated skeleton scene: a chain of two joints carrying segments, and free
/// points and segments, in two blend groups (one per kind) that blend with each other.
#[derive(Clone, Debug)]
struct Sketch {
    /// The angles of the two joints (degrees).
    angles: [f64; 2],
    /// Free points: centre, radius, strength.
    points: Vec<([f64; 3], f64, f64)>,
    /// Free segments: ends and radius.
    segments: Vec<([f64; 3], [f64; 3], f64)>,
    blend: &'static str,
}

impl Sketch {
    fn text(&self) -> String {
        let mut t = format!(
            "[domain]\nmin = [-1.2, -1.2, -1.2]\nmax = [1.2, 1.2, 1.2]\n[mesh]\nresolution = 36\n\
             [skeleton]\nblend = \"{}\"\n{}radius = 0.15\n\
             [skeleton.groups]\nbones = []\nfree = [\"bones\"]\n\
             [[skeleton.joint]]\nname = \"j1\"\nat = [-0.6, -0.3, 0]\naxes = [\"z\"]\nangles = {}\n\
             [[skeleton.joint]]\nname = \"j2\"\nparent = \"j1\"\nat = [0.5, 0, 0]\naxes = [\"z\"]\nangles = {}\n\
             [[skeleton.segment]]\na = [0, 0, 0]\nb = [0.5, 0, 0]\njoint = \"j1\"\ngroup = \"bones\"\n\
             [[skeleton.segment]]\na = [0, 0, 0]\nb = [0.4, 0, 0]\njoint = \"j2\"\ngroup = \"bones\"\n\
             [[skeleton.point]]\nat = [0.4, 0, 0]\njoint = \"j2\"\ngroup = \"bones\"\n",
            self.blend,
            if self.blend == "convolution" { "kernel = \"wyvill\"\n" } else { "" },
            self.angles[0],
            self.angles[1]
        );
        for (i, (c, r, s)) in self.points.iter().enumerate() {
            // Colours that differ from element to element, so that an incremental run's
            // colours are compared with a fresh run's too.
            let colour = [0.1 + 0.2 * (i % 4) as f64, 0.9 - 0.3 * (i % 3) as f64, 0.5];
            t += &format!(
                "[[skeleton.point]]\nat = {c:?}\nradius = {r:?}\nstrength = {s:?}\ngroup = \"free\"\ncolor = {colour:?}\n"
            );
        }
        for (a, b, r) in &self.segments {
            t += &format!(
                "[[skeleton.segment]]\na = {a:?}\nb = {b:?}\nradius = {r:?}\ngroup = \"free\"\n"
            );
        }
        t
    }

    fn scene(&self) -> Scene {
        Scene::parse(&self.text(), "<sketch>").expect("a valid sketch")
    }
}

#[derive(Clone, Debug)]
enum Edit {
    Move(usize, [f64; 3]),
    Radius(usize, f64),
    Strength(usize, f64),
    Angle(usize, f64),
    AddPoint([f64; 3]),
    AddSegment([f64; 3], [f64; 3]),
    Remove(usize),
}

fn coord() -> impl Strategy<Value = f64> {
    -0.8f64..0.8
}

fn point() -> impl Strategy<Value = [f64; 3]> {
    [coord(), coord(), coord()]
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (0usize..8, point()).prop_map(|(i, p)| Edit::Move(i, p)),
        (0usize..8, 0.08f64..0.25).prop_map(|(i, r)| Edit::Radius(i, r)),
        (0usize..8, 0.5f64..1.5).prop_map(|(i, s)| Edit::Strength(i, s)),
        (0usize..2, -60f64..60.0).prop_map(|(j, a)| Edit::Angle(j, a)),
        point().prop_map(Edit::AddPoint),
        (point(), point()).prop_map(|(a, b)| Edit::AddSegment(a, b)),
        (0usize..8).prop_map(Edit::Remove),
    ]
}

impl Sketch {
    fn apply(&mut self, e: &Edit) {
        let n = self.points.len() + self.segments.len();
        match *e {
            Edit::Move(i, p) if n > 0 => {
                let i = i % n;
                if i < self.points.len() {
                    self.points[i].0 = p;
                } else {
                    let s = &mut self.segments[i - self.points.len()];
                    let d = [s.1[0] - s.0[0], s.1[1] - s.0[1], s.1[2] - s.0[2]];
                    *s = (p, [p[0] + d[0], p[1] + d[1], p[2] + d[2]], s.2);
                }
            }
            Edit::Radius(i, r) if n > 0 => {
                let i = i % n;
                if i < self.points.len() {
                    self.points[i].1 = r;
                } else {
                    self.segments[i - self.points.len()].2 = r;
                }
            }
            Edit::Strength(i, s) if !self.points.is_empty() => {
                let i = i % self.points.len();
                self.points[i].2 = s;
            }
            Edit::Angle(j, a) => self.angles[j] = a,
            Edit::AddPoint(p) => self.points.push((p, 0.15, 1.0)),
            Edit::AddSegment(a, b) if a != b => self.segments.push((a, b, 0.12)),
            // Keep one free element of each kind, so that the groups stay as they are
            // (a group losing its last element changes the cliques: a full run, tested
            // separately).
            Edit::Remove(i) if n > 2 => {
                let i = i % n;
                if i < self.points.len() && self.points.len() > 1 {
                    self.points.remove(i);
                } else if i >= self.points.len() && self.segments.len() > 1 {
                    self.segments.remove(i - self.points.len());
                }
            }
            _ => {}
        }
    }
}

fn sketch(blend: &'static str) -> Sketch {
    Sketch {
        angles: [20.0, 30.0],
        points: vec![([0.3, 0.5, 0.1], 0.2, 1.0), ([-0.5, 0.4, -0.3], 0.15, 1.0)],
        segments: vec![([0.2, -0.6, 0.0], [0.6, -0.4, 0.3], 0.12)],
        blend,
    }
}

fn blend() -> impl Strategy<Value = &'static str> {
    prop_oneof![Just("convolution"), Just("union"), Just("super-elliptic")]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// Every step of a random edit sequence: the incremental mesh is the fresh one, bit for
    /// bit (same vertices in the same order, same normals, same triangles, same colours,
    /// most of which an incremental run takes over from the last).
    #[test]
    fn random_edits_give_the_fresh_mesh(blend in blend(), edits in prop::collection::vec(edit(), 1..6)) {
        let mut s = sketch(blend);
        let o = Overrides::default();
        let mut live = Live::new();
        let first = live.mesh(&s.scene(), &o).unwrap();
        prop_assert_eq!(&first.mesh, &s.scene().mesh(&o).unwrap().mesh);
        for e in &edits {
            s.apply(e);
            let scene = s.scene();
            let meshed = live.mesh(&scene, &o).unwrap();
            let run = live.last_run().unwrap().clone();
            prop_assert!(run.incremental, "{:?} ran from scratch: {:?}", e, run.full_because);
            let fresh = scene.mesh(&o).unwrap();
            prop_assert!(!fresh.mesh.is_empty());
            prop_assert_eq!(fresh.mesh.colors.len(), fresh.mesh.vertex_count(), "painted");
            prop_assert_eq!(&meshed.mesh, &fresh.mesh, "after {:?}", e);
        }
    }
}

/// Edits outside the skeleton's elements (groups, blend) run from scratch and still give
/// the fresh mesh.
#[test]
fn global_changes_run_from_scratch() {
    let o = Overrides::default();
    let mut live = Live::new();
    let s = sketch("convolution");
    live.mesh(&s.scene(), &o).unwrap();
    let mut other = s.clone();
    other.blend = "sum";
    let meshed = live.mesh(&other.scene(), &o).unwrap();
    let run = live.last_run().unwrap();
    assert!(!run.incremental);
    assert!(run.full_because.as_deref().unwrap().contains("blend"), "{run:?}");
    assert_eq!(meshed.mesh, other.scene().mesh(&o).unwrap().mesh);
    // Another resolution: another lattice.
    let finer = Overrides { resolution: Some(Resolution::Samples(40)), ..Overrides::default() };
    let meshed = live.mesh(&other.scene(), &finer).unwrap();
    assert!(!live.last_run().unwrap().incremental);
    assert_eq!(meshed.mesh, other.scene().mesh(&finer).unwrap().mesh);
    // The last free elements removed: their group has none, the cliques change.
    let mut fewer = other.clone();
    fewer.points.clear();
    fewer.segments.clear();
    let meshed = live.mesh(&fewer.scene(), &finer).unwrap();
    assert!(!live.last_run().unwrap().incremental);
    assert_eq!(meshed.mesh, fewer.scene().mesh(&finer).unwrap().mesh);
}

/// The chapter-6 hand: one finger joint bent by 10 degrees, re-meshed incrementally, is the
/// fresh run's mesh; and most of it was reused.
#[test]
fn hand_finger_bent_by_ten_degrees() {
    let text = std::fs::read_to_string("../../examples/skeleton/hand.toml").unwrap();
    let o = Overrides { resolution: Some(Resolution::Samples(64)), ..Overrides::default() };
    let mut live = Live::new();
    live.mesh(&Scene::parse(&text, "hand.toml").unwrap(), &o).unwrap();
    let joint =
        "name = \"middle2\"\nparent = \"middle1\"\nat = [0.9, 0, 0]\naxes = [\"y\"]\nangles = 30";
    assert!(text.contains(joint));
    let bent = text.replacen(joint, &joint.replace("angles = 30", "angles = 40"), 1);
    let scene = Scene::parse(&bent, "hand.toml").unwrap();
    let meshed = live.mesh(&scene, &o).unwrap();
    let run = live.last_run().unwrap();
    assert!(run.incremental, "{run:?}");
    let fresh = scene.mesh(&o).unwrap();
    assert_eq!(meshed.mesh, fresh.mesh);
    assert!(run.reuse.reused_vertices > 2 * run.reuse.placed_vertices, "{run:?}");
    let all: u64 = match &fresh.stats {
        skelform::Stats::Grid(s) => s.samples,
        _ => unreachable!(),
    };
    assert!(run.reuse.resampled * 4 < all, "{run:?} of {all}");
}

/// Progressive meshing: coarse levels first, the last the fresh run's mesh; a cancellation
/// from the first callback stops it.
#[test]
fn progressive_levels_and_cancellation() {
    let s = sketch("convolution").scene();
    let o = Overrides::default();
    let mut live = Live::new();
    let mut seen = Vec::new();
    let last = live
        .mesh_progressive(&s, &o, 3, |level, m| seen.push((level, m.mesh.vertex_count())))
        .unwrap();
    assert_eq!(seen.iter().map(|l| l.0).collect::<Vec<_>>(), [0, 1, 2]);
    assert!(seen[0].1 < seen[1].1 && seen[1].1 < seen[2].1, "{seen:?}");
    assert_eq!(last.mesh, s.mesh(&o).unwrap().mesh);

    let control = Control::default();
    let o = Overrides { control: control.clone(), ..Overrides::default() };
    let mut calls = 0;
    let err = live
        .mesh_progressive(&s, &o, 3, |_, _| {
            calls += 1;
            control.cancel();
        })
        .unwrap_err();
    assert!(err.is_cancelled(), "{err}");
    assert_eq!(calls, 1);
}

/// An edit cancelled by a newer one (the studio's case) does not cost the next a run from
/// scratch: the cancelled update had already sampled its boxes with its own field, and the
/// next samples them again with the newest, giving the fresh run's mesh.
#[test]
fn a_cancelled_edit_leaves_the_next_incremental_and_exact() {
    let o = Overrides::default();
    let base = sketch("convolution");
    let mut live = Live::new();
    live.mesh(&base.scene(), &o).unwrap();

    // The cancelled edit moves one free point along x; the newest moves the other free
    // point to the same height instead, far from the first: its re-extracted slabs cross
    // the cancelled edit's samples, which must be taken again with the newest field.
    let mut cancelled = base.clone();
    cancelled.points[0].0[0] += 0.25;
    let control = Control::default();
    control.cancel();
    let stopped = Overrides { control, ..Overrides::default() };
    let err = live.mesh(&cancelled.scene(), &stopped).unwrap_err();
    assert!(err.is_cancelled(), "{err}");

    let mut newest = base.clone();
    newest.points[1].0[2] = base.points[0].0[2];
    let s = newest.scene();
    let m = live.mesh(&s, &o).unwrap();
    let run = live.last_run().unwrap();
    assert!(run.incremental, "{run:?}");
    assert_eq!(m.mesh, s.mesh(&o).unwrap().mesh);

    // And the state is whole again: a plain edit after it is exact too.
    let mut after = newest.clone();
    after.angles[0] -= 10.0;
    after.points[0].0[1] -= 0.1;
    let s = after.scene();
    let m = live.mesh(&s, &o).unwrap();
    assert!(live.last_run().unwrap().incremental);
    assert_eq!(m.mesh, s.mesh(&o).unwrap().mesh);
}
