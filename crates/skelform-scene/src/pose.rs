//! Joints and poses in `[skeleton]`: a tree of named joints, elements attached to them, and
//! named poses that set the joints' angles (DIS §2.7 and ch. 6: the hand is articulated by
//! the angles at the finger bases and knuckles).
//!
//! ```toml
//! [[skeleton.joint]]
//! name = "index1"              # first knuckle
//! parent = "palm"              # optional: a root joint hangs in world coordinates
//! at = [0.3, 0.1, 0]           # the joint's origin in its parent's frame
//! orient = [["z", 10]]         # optional fixed turns of the joint's frame, in order
//! axes = ["z", "y"]            # what the angles turn about, in order (θ then φ)
//! angles = [10, 15]            # default angles in degrees (default 0)
//!
//! [[skeleton.segment]]
//! a = [0, 0, 0]                # in the frame of the joint below
//! b = [0.75, 0, 0]
//! joint = "index1"
//!
//! [skeleton.poses.grip]        # a named pose: angles of some joints; others keep defaults
//! index1 = [10, 60]
//! index2 = 80
//! ```
//!
//! A joint's frame is its parent's frame moved to `at`, turned by `orient` (fixed), then by
//! the angles about `axes` (`R(axis₁, a₁)·R(axis₂, a₂)`, each axis in the frame the earlier
//! turns leave). An element attached to a joint is written in that joint's frame, so a bone
//! reads as "from the knuckle, along x"; posing rotates frames, never interpolates
//! endpoints, so every element keeps its shape and size (DIS fig. 2.6).

use std::collections::{BTreeMap, HashMap};

use glam::{DAffine3, DQuat};
use serde::Deserialize;
use skelform_field::DVec3;
use skelform_skeleton::{Articulated, JointId, Pose, Skeleton, SkeletonError};
use toml::Spanned;

use crate::SceneError;
use crate::diag::At;

/// The pose that every scene with joints has: each joint at its default angles.
pub const REST: &str = "rest";

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct JointSpec {
    name: Spanned<String>,
    parent: Option<Spanned<String>>,
    at: Option<Spanned<[f64; 3]>>,
    orient: Option<Spanned<Vec<Turn>>>,
    axes: Option<Spanned<Vec<Spanned<String>>>>,
    angles: Option<Spanned<Angles>>,
}

/// A fixed turn of a joint's frame: an axis and degrees.
type Turn = (Spanned<String>, f64);

/// One angle (a joint with one axis) or a list of them.
#[derive(Deserialize)]
#[serde(untagged)]
pub(crate) enum Angles {
    One(f64),
    Many(Vec<f64>),
}

impl Angles {
    fn to_vec(&self) -> Vec<f64> {
        match self {
            Angles::One(a) => vec![*a],
            Angles::Many(v) => v.clone(),
        }
    }
}

/// A pose: joint name → angles.
pub(crate) type PoseSpec = BTreeMap<Spanned<String>, Spanned<Angles>>;

/// The joints and poses of a `[skeleton]`, as read.
pub(crate) struct Spec<'a> {
    pub joints: Option<&'a [JointSpec]>,
    pub poses: Option<&'a BTreeMap<Spanned<String>, PoseSpec>>,
    pub pose: Option<&'a Spanned<String>>,
}

/// Which pose to build, from outside the file (the command line's `--pose`), and the file's
/// name for messages that have no position in it.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Choice<'a> {
    pub pose: Option<&'a str>,
    pub toward: Option<&'a crate::PoseBlend>,
    pub origin: &'a str,
}

/// What a scene's articulation is, for `skelform info` and the command line.
#[derive(Clone, Debug, PartialEq)]
pub struct Articulation {
    /// Joint names in file order.
    pub joints: Vec<String>,
    /// Pose names: `rest` first, then the file's in name order.
    pub poses: Vec<String>,
    /// The pose the field was built in.
    pub pose: String,
    /// Each joint's frame in world coordinates in that pose (in the order of `joints`): its
    /// origin is where the joint is, and an element point `q` of the joint lies at
    /// `frame.transform_point3(q)`.
    pub frames: Vec<DAffine3>,
}

/// Element ranges of the skeleton and the joint each is attached to (`None`: world).
pub(crate) type Marks<'a> = Vec<(std::ops::Range<usize>, Option<&'a Spanned<String>>)>;

/// Attaches the marked elements to their joints and poses the skeleton. Without joints,
/// poses or attached elements, the skeleton is returned as it is.
pub(crate) fn articulate(
    spec: &Spec,
    skeleton: Skeleton,
    marks: &Marks,
    choice: Choice,
    at: At,
) -> Result<(Skeleton, Option<Articulation>), SceneError> {
    let joints = spec.joints.unwrap_or(&[]);
    let attached = marks.iter().any(|(_, j)| j.is_some());
    if joints.is_empty() && spec.poses.is_none() && spec.pose.is_none() && !attached {
        if let Some(p) = choice.pose.or(choice.toward.map(|b| b.pose.as_str())) {
            return Err(SceneError::Invalid {
                path: choice.origin.to_string(),
                message: format!("cannot take pose '{p}': the scene has no joints or poses"),
            });
        }
        return Ok((skeleton, None));
    }
    let err = |offset: usize, e: SkeletonError| at(offset, e.to_string());

    // Names, parents, cycles.
    let mut index: HashMap<&str, usize> = HashMap::new();
    for (i, j) in joints.iter().enumerate() {
        let name = j.name.get_ref().as_str();
        if name.is_empty() {
            return Err(at(j.name.span().start, "a joint needs a non-empty name".into()));
        }
        if index.insert(name, i).is_some() {
            return Err(err(j.name.span().start, SkeletonError::DuplicateJoint(name.into())));
        }
    }
    let known = || {
        let names: Vec<&str> = joints.iter().map(|j| j.name.get_ref().as_str()).collect();
        if names.is_empty() { "none".to_string() } else { names.join(", ") }
    };
    let mut parent: Vec<Option<usize>> = Vec::with_capacity(joints.len());
    for j in joints {
        parent.push(match &j.parent {
            None => None,
            Some(p) => Some(*index.get(p.get_ref().as_str()).ok_or_else(|| {
                at(
                    p.span().start,
                    format!(
                        "joint '{}': unknown parent '{}' (joints: {})",
                        j.name.get_ref(),
                        p.get_ref(),
                        known()
                    ),
                )
            })?),
        });
    }
    // Parents before children; a joint met again on its own chain of parents is a cycle.
    let mut order: Vec<usize> = Vec::with_capacity(joints.len());
    let mut state = vec![0u8; joints.len()]; // 0 new, 1 on the current chain, 2 placed
    for start in 0..joints.len() {
        let mut chain = Vec::new();
        let mut j = Some(start);
        while let Some(i) = j {
            match state[i] {
                2 => break,
                1 => {
                    let from = chain.iter().position(|&c| c == i).unwrap_or(0);
                    let names: Vec<&str> = chain[from..]
                        .iter()
                        .chain([&i])
                        .map(|&c: &usize| joints[c].name.get_ref().as_str())
                        .collect();
                    let p = joints[i]
                        .parent
                        .as_ref()
                        .map_or(joints[i].name.span().start, |p| p.span().start);
                    return Err(at(
                        p,
                        format!(
                            "joint '{}' is its own ancestor: the parents form a cycle {}",
                            joints[i].name.get_ref(),
                            names.join(" → ")
                        ),
                    ));
                }
                _ => {
                    state[i] = 1;
                    chain.push(i);
                    j = parent[i];
                }
            }
        }
        for &c in chain.iter().rev() {
            state[c] = 2;
            order.push(c);
        }
    }

    // The joints, in that order.
    let mut art = Articulated::new(skeleton);
    let mut id: Vec<Option<JointId>> = vec![None; joints.len()];
    for &i in &order {
        let j = &joints[i];
        let name = j.name.get_ref();
        let offset = j.at.as_ref().map_or(DVec3::ZERO, |a| DVec3::from_array(*a.get_ref()));
        if !offset.is_finite() {
            let o = j.at.as_ref().map_or(j.name.span().start, |a| a.span().start);
            return Err(err(o, SkeletonError::NonFinite));
        }
        let mut rest = DQuat::IDENTITY;
        if let Some(o) = &j.orient {
            for (axis, degrees) in o.get_ref() {
                let a = parse_axis(axis, at)?;
                if !degrees.is_finite() {
                    return Err(err(o.span().start, SkeletonError::NonFinite));
                }
                rest *= DQuat::from_axis_angle(a, degrees.to_radians());
            }
        }
        let jid = art
            .add_joint(name, parent[i].and_then(|p| id[p]), offset, rest)
            .map_err(|e| err(j.name.span().start, e))?;
        id[i] = Some(jid);
        let axes: Vec<DVec3> = match &j.axes {
            Some(list) => {
                list.get_ref().iter().map(|a| parse_axis(a, at)).collect::<Result<_, _>>()?
            }
            None => Vec::new(),
        };
        let defaults = match &j.angles {
            Some(a) => a.get_ref().to_vec(),
            None => vec![0.0; axes.len()],
        };
        let angles_at = j.angles.as_ref().map_or(j.name.span().start, |a| a.span().start);
        art.set_axes(jid, &axes, &defaults).map_err(|e| err(angles_at, e))?;
    }
    let lookup = |name: &Spanned<String>, what: &str| {
        index.get(name.get_ref().as_str()).and_then(|&i| id[i]).ok_or_else(|| {
            at(
                name.span().start,
                format!("{what}unknown joint '{}' (joints: {})", name.get_ref(), known()),
            )
        })
    };

    // Elements onto their joints.
    for (range, joint) in marks {
        if let Some(name) = joint {
            let jid = lookup(name, "")?;
            for e in range.clone() {
                art.attach(e, Some(jid)).map_err(|e| err(name.span().start, e))?;
            }
        }
    }

    // Poses: every one is checked, the chosen one is built.
    let mut poses: Vec<(String, Pose)> = vec![(REST.to_string(), art.default_pose())];
    for (name, spec) in spec.poses.into_iter().flatten() {
        if name.get_ref() == REST {
            return Err(at(
                name.span().start,
                format!(
                    "'{REST}' is the pose of the joints' default angles and cannot be redefined; \
                     choose another name"
                ),
            ));
        }
        let mut pose = art.default_pose();
        for (joint, angles) in spec {
            let jid = lookup(joint, &format!("pose '{}': ", name.get_ref()))?;
            art.set_angles(&mut pose, jid, &angles.get_ref().to_vec())
                .map_err(|e| err(angles.span().start, e))?;
        }
        poses.push((name.get_ref().clone(), pose));
    }
    let names: Vec<String> = poses.iter().map(|(n, _)| n.clone()).collect();
    let chosen = match (choice.pose, spec.pose) {
        (Some(p), _) => p.to_string(),
        (None, Some(p)) => p.get_ref().clone(),
        (None, None) => REST.to_string(),
    };
    let pose = match poses.iter().find(|(n, _)| *n == chosen) {
        Some((_, p)) => p,
        None => {
            let message =
                format!("unknown pose '{chosen}'; the scene's poses are: {}", names.join(", "));
            return Err(match (choice.pose, spec.pose) {
                (None, Some(p)) => at(p.span().start, message),
                _ => SceneError::Invalid { path: choice.origin.to_string(), message },
            });
        }
    };
    let (pose, chosen) = match choice.toward {
        None => (pose.clone(), chosen),
        Some(b) => {
            let Some((_, target)) = poses.iter().find(|(n, _)| *n == b.pose) else {
                return Err(SceneError::Invalid {
                    path: choice.origin.to_string(),
                    message: format!(
                        "unknown pose '{}'; the scene's poses are: {}",
                        b.pose,
                        names.join(", ")
                    ),
                });
            };
            if !(0.0..=1.0).contains(&b.t) {
                return Err(SceneError::Invalid {
                    path: choice.origin.to_string(),
                    message: format!(
                        "the way from one pose to another runs from 0 to 1 (got {})",
                        b.t
                    ),
                });
            }
            (pose.interpolate(target, b.t), format!("{chosen} → {} at {}", b.pose, b.t))
        }
    };
    let posed = art.posed(&pose).map_err(|e| SceneError::Invalid {
        path: choice.origin.to_string(),
        message: format!("pose '{chosen}': {e}"),
    })?;
    let frames = art.frames(&pose);
    let articulation = Articulation {
        joints: joints.iter().map(|j| j.name.get_ref().clone()).collect(),
        poses: names,
        pose: chosen,
        frames: id.iter().map(|j| j.map_or(DAffine3::IDENTITY, |j| frames[j.index()])).collect(),
    };
    Ok((posed, Some(articulation)))
}

fn parse_axis(axis: &Spanned<String>, at: At) -> Result<DVec3, SceneError> {
    Ok(match axis.get_ref().as_str() {
        "x" | "+x" => DVec3::X,
        "y" | "+y" => DVec3::Y,
        "z" | "+z" => DVec3::Z,
        "-x" => DVec3::NEG_X,
        "-y" => DVec3::NEG_Y,
        "-z" => DVec3::NEG_Z,
        other => {
            return Err(at(
                axis.span().start,
                format!("unknown axis '{other}'; expected x, y, z, -x, -y or -z"),
            ));
        }
    })
}

#[cfg(test)]
mod tests {
    use crate::{LoadOptions, Scene, SceneError};
    use skelform_field::{DVec3, Field};

    const HEAD: &str = "[domain]\nmin = [-2, -2, -2]\nmax = [2, 2, 2]\n[skeleton]\nradius = 0.1\n";

    /// A finger of two bones along x: a knuckle at the origin turning about z then y, a
    /// middle joint one unit further turning about y; the tip bone is 0.6 long.
    const FINGER: &str = r#"
[[skeleton.joint]]
name = "knuckle"
axes = ["z", "y"]
angles = [0, 0]
[[skeleton.joint]]
name = "middle"
parent = "knuckle"
at = [1, 0, 0]
axes = ["y"]
[[skeleton.segment]]
a = [0, 0, 0]
b = [1, 0, 0]
joint = "knuckle"
[[skeleton.segment]]
a = [0, 0, 0]
b = [0.6, 0, 0]
joint = "middle"
[skeleton.poses.bent]
middle = 90
[skeleton.poses.turned]
knuckle = [90, 0]
middle = 90
"#;

    fn parse(body: &str, pose: Option<&str>) -> Result<Scene, SceneError> {
        let options = LoadOptions { pose: pose.map(str::to_string), ..Default::default() };
        Scene::parse_with(&format!("{HEAD}{body}"), "s.toml", &options)
    }

    /// The error's line (counting HEAD's five lines), column and message.
    fn error(body: &str) -> (usize, usize, String) {
        crate::testing::error_position(parse(body, None), body)
    }

    /// Where the tip bone's end is: the point on its axis where the field is lowest beyond
    /// the middle joint is hard to find, so probe the field at the expected places instead.
    fn inside(s: &Scene, p: [f64; 3]) -> bool {
        s.field.eval(DVec3::from_array(p)) < 0.0
    }

    #[test]
    fn a_child_bone_follows_its_parents_rotation() {
        let rest = parse(FINGER, None).unwrap();
        let art = rest.articulation.as_ref().unwrap();
        assert_eq!(art.pose, "rest");
        assert_eq!(art.poses, ["rest", "bent", "turned"]);
        assert_eq!(art.joints, ["knuckle", "middle"]);
        // Rest: straight along x to 1.6.
        assert!(inside(&rest, [1.5, 0.0, 0.0]) && !inside(&rest, [1.0, 0.0, -0.5]));
        // Bent 90° at the middle joint: the tip bone points down (−z) from (1, 0, 0).
        let bent = parse(FINGER, Some("bent")).unwrap();
        assert!(inside(&bent, [1.0, 0.0, -0.5]) && !inside(&bent, [1.5, 0.0, 0.0]));
        assert!(inside(&bent, [0.5, 0.0, 0.0]), "the first bone stays");
        // Turned 90° about z at the knuckle as well: the whole finger along y, the tip down.
        let turned = parse(FINGER, Some("turned")).unwrap();
        assert!(inside(&turned, [0.0, 0.5, 0.0]) && inside(&turned, [0.0, 1.0, -0.5]));
        assert!(!inside(&turned, [0.5, 0.0, 0.0]) && !inside(&turned, [1.0, 0.0, -0.5]));
        // A convolution surface passes through the segment's free end (DIS §5.6.11): the
        // tip is where it was, whatever the pose, so lengths are kept.
        for (s, tip, dir) in [
            (&rest, [1.6, 0.0, 0.0], DVec3::X),
            (&bent, [1.0, 0.0, -0.6], DVec3::NEG_Z),
            (&turned, [0.0, 1.0, -0.6], DVec3::NEG_Z),
        ] {
            let tip = DVec3::from_array(tip);
            let (a, b) = (s.field.eval(tip - dir * 0.01), s.field.eval(tip + dir * 0.01));
            assert!(a < 0.0 && b > 0.0, "{tip} {a} {b}");
        }
        // The scene's own default pose, and the command line winning over it.
        let with_default = format!("{FINGER}\n");
        let text =
            with_default.replacen("[[skeleton.joint]]", "pose = \"bent\"\n[[skeleton.joint]]", 1);
        let s = parse(&text, None).unwrap();
        assert_eq!(s.articulation.as_ref().unwrap().pose, "bent");
        let s = parse(&text, Some("rest")).unwrap();
        assert!(inside(&s, [1.5, 0.0, 0.0]));
        // Children may come before their parents in the file.
        let (first, second) =
            FINGER.split_at(FINGER.find("[[skeleton.joint]]\nname = \"middle\"").unwrap());
        let (joint2, rest_of_file) = second.split_at(second.find("[[skeleton.segment]]").unwrap());
        let reordered = format!("{joint2}{first}{rest_of_file}");
        let s = parse(&reordered, Some("turned")).unwrap();
        assert!(inside(&s, [0.0, 1.0, -0.5]) && !inside(&s, [1.0, 0.0, -0.5]));
        assert_eq!(s.articulation.as_ref().unwrap().joints, ["middle", "knuckle"]);
        // Seeds follow the pose.
        assert!(
            bent.continuation
                .seeds
                .iter()
                .any(|p| (*p - DVec3::new(1.0, 0.0, -0.3)).length() < 1e-12)
        );
    }

    #[test]
    fn an_unknown_pose_lists_the_known_ones() {
        match parse(FINGER, Some("fist")) {
            Err(SceneError::Invalid { path, message }) => {
                assert_eq!(path, "s.toml");
                assert!(message.contains("unknown pose 'fist'"), "{message}");
                assert!(message.contains("rest, bent, turned"), "{message}");
            }
            r => panic!("{:?}", r.map(|_| ())),
        }
        let text = FINGER.replacen("[[skeleton.joint]]", "pose = \"fist\"\n[[skeleton.joint]]", 1);
        let (l, c, m) = error(&text);
        assert_eq!((l, c), (7, 8), "{m}");
        assert!(m.contains("unknown pose 'fist'") && m.contains("bent"), "{m}");
        // A pose for a scene without joints.
        let plain = "[[skeleton.point]]\nat = [0, 0, 0]\n";
        match parse(plain, Some("open")) {
            Err(SceneError::Invalid { message, .. }) => {
                assert!(message.contains("no joints"), "{message}")
            }
            r => panic!("{:?}", r.map(|_| ())),
        }
        assert!(parse(plain, None).unwrap().articulation.is_none());
        let formula = "[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\n[field]\nformula = \"x\"\n";
        let options = LoadOptions { pose: Some("open".into()), ..Default::default() };
        match Scene::parse_with(formula, "f.toml", &options) {
            Err(SceneError::Invalid { message, .. }) => {
                assert!(message.contains("no [skeleton] joints"), "{message}")
            }
            r => panic!("{:?}", r.map(|_| ())),
        }
    }

    #[test]
    fn joint_errors_name_the_joint_and_its_place() {
        let seg = "[[skeleton.segment]]\na = [0, 0, 0]\nb = [1, 0, 0]\n";
        // Missing parent: at the parent's name.
        let (l, c, m) = error(&format!(
            "[[skeleton.joint]]\nname = \"a\"\n[[skeleton.joint]]\nname = \"b\"\nparent = \"hand\"\n{seg}"
        ));
        assert_eq!((l, c), (10, 10), "{m}");
        assert!(m.contains("joint 'b': unknown parent 'hand' (joints: a, b)"), "{m}");
        // Duplicate name: at the second.
        let (l, _, m) = error(&format!(
            "[[skeleton.joint]]\nname = \"a\"\n[[skeleton.joint]]\nname = \"a\"\n{seg}"
        ));
        assert_eq!(l, 9, "{m}");
        assert!(m.contains("joint 'a' is defined twice"), "{m}");
        // A cycle of parents.
        let (l, _, m) = error(&format!(
            "[[skeleton.joint]]\nname = \"a\"\nparent = \"c\"\n[[skeleton.joint]]\nname = \"b\"\nparent = \"a\"\n\
             [[skeleton.joint]]\nname = \"c\"\nparent = \"b\"\n{seg}"
        ));
        assert_eq!(l, 8, "{m}");
        assert!(m.contains("joint 'a' is its own ancestor") && m.contains("a → c → b → a"), "{m}");
        let (_, _, m) = error(&format!("[[skeleton.joint]]\nname = \"a\"\nparent = \"a\"\n{seg}"));
        assert!(m.contains("cycle a → a"), "{m}");
        // An element on an unknown joint: at its name.
        let (l, c, m) = error(&format!("[[skeleton.joint]]\nname = \"a\"\n{seg}joint = \"b\"\n"));
        assert_eq!((l, c), (11, 9), "{m}");
        assert!(m.contains("unknown joint 'b' (joints: a)"), "{m}");
        let (_, _, m) = error(&format!("{seg}joint = \"b\"\n"));
        assert!(m.contains("unknown joint 'b' (joints: none)"), "{m}");
        // A pose naming an unknown joint, or giving the wrong number of angles.
        let (l, c, m) = error(&format!("{FINGER}[skeleton.poses.x]\nknuckel = [1, 2]\n"));
        assert!(m.contains("pose 'x': unknown joint 'knuckel'"), "{m}");
        assert_eq!((l, c), (30, 1), "{m}");
        let (l, c, m) = error(&format!("{FINGER}[skeleton.poses.x]\nknuckle = 30\n"));
        assert!(
            m.contains("joint 'knuckle' turns about 2 axes, so it takes 2 angles (got 1)"),
            "{m}"
        );
        assert_eq!((l, c), (30, 11), "{m}");
        let (_, _, m) = error(&format!("{FINGER}[skeleton.poses.rest]\nknuckle = [3, 0]\n"));
        assert!(m.contains("'rest' is the pose of the joints' default angles"), "{m}");
        // Default angles that do not match the axes; an unknown axis.
        let (l, _, m) = error(&format!(
            "[[skeleton.joint]]\nname = \"a\"\naxes = [\"z\"]\nangles = [1, 2]\n{seg}"
        ));
        assert_eq!(l, 9, "{m}");
        assert!(m.contains("takes 1 angles (got 2)"), "{m}");
        let (l, c, m) =
            error(&format!("[[skeleton.joint]]\nname = \"a\"\naxes = [\"z\", \"w\"]\n{seg}"));
        assert_eq!((l, c), (8, 14), "{m}");
        assert!(m.contains("unknown axis 'w'"), "{m}");
        // Unknown keys in a joint are refused like everywhere else.
        let (l, _, m) = error(&format!("[[skeleton.joint]]\nname = \"a\"\nangle = 3\n{seg}"));
        assert_eq!(l, 8, "{m}");
        assert!(m.contains("angle"), "{m}");
    }

    #[test]
    fn fixed_orientation_and_every_element_kind_attach() {
        // A joint turned 90° about z carries a polyline, a point, a triangle and a curve:
        // what is written along +x ends up along +y.
        let s = parse(
            r#"
[[skeleton.joint]]
name = "j"
at = [0.2, 0, 0]
orient = [["z", 90]]
[[skeleton.polyline]]
points = [[0, 0, 0], [0.5, 0, 0], [1, 0, 0]]
joint = "j"
[[skeleton.point]]
at = [1.5, 0, 0]
joint = "j"
[[skeleton.triangle]]
vertices = [[0, 0, 0.5], [0.4, 0, 0.5], [0, 0.4, 0.5]]
joint = "j"
[[skeleton.curve]]
bezier = [[0, 0, -0.5], [0.3, 0, -0.5], [0.6, 0, -0.5], [0.9, 0, -0.5]]
joint = "j"
"#,
            None,
        )
        .unwrap();
        for p in [[0.2, 0.75, 0.0], [0.2, 1.5, 0.0], [0.15, 0.1, 0.5], [0.2, 0.45, -0.5]] {
            assert!(inside(&s, p), "{p:?}");
        }
        for p in [[0.75, 0.0, 0.0], [1.5, 0.0, 0.0], [0.45, 0.0, -0.5]] {
            assert!(!inside(&s, p), "{p:?}");
        }
    }
}
