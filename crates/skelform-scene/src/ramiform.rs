//! `[ramiform]`: a branching skeleton whose field is the recursive maximum of DIS eqs. 3.3
//! and 5.36 (see [`skelform_skeleton::ramiform`]).
//!
//! ```toml
//! [ramiform]
//! [[ramiform.limb]]
//! name = "trunk"          # needed by limbs that hang from it
//! a = [0, 0, 0]           # roots only: a child starts at its parent's end
//! b = [0, 0, 1]
//! [[ramiform.limb]]
//! parent = "trunk"
//! b = [0.4, 0, 1.6]
//! radius = 0.1            # leaves only: a parent's radius is matched to its children's
//! ```

use std::collections::BTreeMap;
use std::sync::Arc;

use serde::Deserialize;
use skelform_field::DVec3;
use skelform_skeleton::ramiform::MAX_LIMBS;
use skelform_skeleton::{Ramiform, RamiformField, RamiformOptions, SkeletonError};
use toml::Spanned;

use crate::SceneError;
use crate::diag::At;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RamiformSection {
    /// Directions sampled in each joint plane to match the parent's radius.
    directions: Option<Spanned<i64>>,
    limb: Option<Vec<LimbSpec>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LimbSpec {
    name: Option<Spanned<String>>,
    parent: Option<Spanned<String>>,
    a: Option<Spanned<[f64; 3]>>,
    b: Spanned<[f64; 3]>,
    radius: Option<Spanned<f64>>,
}

/// The section built: the field and a point inside each limb.
pub(crate) fn build(
    s: &Spanned<RamiformSection>,
    at: At,
) -> Result<(Arc<RamiformField>, Vec<DVec3>), SceneError> {
    let section_at = s.span().start;
    let s = s.get_ref();
    let mut options = RamiformOptions::default();
    if let Some(d) = &s.directions {
        let v = *d.get_ref();
        if !(8..=100_000).contains(&v) {
            return Err(at(
                d.span().start,
                format!("directions must be from 8 to 100000 (got {v})"),
            ));
        }
        options.directions = v as usize;
    }
    // Counted before any limb is built, so that a huge tree costs only its parse.
    let count = s.limb.as_ref().map_or(0, Vec::len);
    if count > MAX_LIMBS {
        let over = &s.limb.as_ref().map_or(section_at, |l| l[MAX_LIMBS].b.span().start);
        return Err(at(
            *over,
            format!("the ramiform has {count} limbs, over the limit of {MAX_LIMBS}"),
        ));
    }
    let mut tree = Ramiform::new();
    let mut names: BTreeMap<&str, usize> = BTreeMap::new();
    // Where each limb was written, to place errors the tree reports by limb index.
    let mut limb_at = Vec::new();
    let err = |offset: usize, e: SkeletonError| at(offset, e.to_string());
    for l in s.limb.iter().flatten() {
        let b = DVec3::from_array(*l.b.get_ref());
        if !b.is_finite() {
            return Err(err(l.b.span().start, SkeletonError::NonFinite));
        }
        let radius = l.radius.as_ref().map(|r| *r.get_ref());
        let radius_at = l.radius.as_ref().map_or(l.b.span().start, |r| r.span().start);
        let index = match (&l.parent, &l.a) {
            (None, Some(a)) => {
                let av = DVec3::from_array(*a.get_ref());
                if !av.is_finite() {
                    return Err(err(a.span().start, SkeletonError::NonFinite));
                }
                tree.add_root(av, b, radius).map_err(|e| match e {
                    SkeletonError::BadRadius(_) => err(radius_at, e),
                    e => err(l.b.span().start, e),
                })?
            }
            (None, None) => {
                return Err(at(
                    l.b.span().start,
                    "a root limb needs 'a' (where it starts); other limbs name their 'parent'"
                        .into(),
                ));
            }
            (Some(p), Some(a)) => {
                return Err(at(
                    a.span().start,
                    format!(
                        "a limb with a parent starts at the end of '{}': leave 'a' out",
                        p.get_ref()
                    ),
                ));
            }
            (Some(p), None) => {
                let Some(&parent) = names.get(p.get_ref().as_str()) else {
                    let known: Vec<&str> = names.keys().copied().collect();
                    return Err(at(
                        p.span().start,
                        format!(
                            "unknown limb '{}' (a parent must come before its children; named \
                             so far: {})",
                            p.get_ref(),
                            if known.is_empty() { "none".to_string() } else { known.join(", ") }
                        ),
                    ));
                };
                tree.add_child(parent, b, radius).map_err(|e| match e {
                    SkeletonError::BadRadius(_) => err(radius_at, e),
                    SkeletonError::TooDeep { .. } => err(p.span().start, e),
                    e => err(l.b.span().start, e),
                })?
            }
        };
        limb_at.push((l.b.span().start, radius_at));
        if let Some(n) = &l.name
            && names.insert(n.get_ref().as_str(), index).is_some()
        {
            return Err(at(n.span().start, format!("limb '{}' is named twice", n.get_ref())));
        }
    }
    if tree.limbs().is_empty() {
        return Err(at(section_at, "the ramiform has no limbs: add [[ramiform.limb]]".into()));
    }
    let field = RamiformField::new(&tree, &options).map_err(|e| {
        let offset = match &e {
            SkeletonError::LeafNeedsRadius(i) => limb_at.get(*i).map(|l| l.0),
            SkeletonError::ParentRadiusGiven(i) => limb_at.get(*i).map(|l| l.1),
            SkeletonError::JointWorkTooLarge { .. } => {
                s.directions.as_ref().map(|d| d.span().start)
            }
            _ => None,
        };
        err(offset.unwrap_or(section_at), e)
    })?;
    let seeds = field.seed_points();
    Ok((Arc::new(field), seeds))
}

#[cfg(test)]
mod tests {
    use crate::{Scene, SceneError};
    use skelform_field::{DVec3, Field};

    const HEAD: &str = "[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 2]\n";
    const TREE: &str = "[ramiform]\n[[ramiform.limb]]\nname = \"trunk\"\na = [0, 0, 0]\nb = [0, 0, 1]\n\
                        [[ramiform.limb]]\nparent = \"trunk\"\nb = [0.4, 0, 1.5]\nradius = 0.1\n\
                        [[ramiform.limb]]\nparent = \"trunk\"\nb = [-0.4, 0, 1.5]\nradius = 0.1\n";

    fn parse(body: &str) -> Result<Scene, SceneError> {
        Scene::parse(&format!("{HEAD}{body}"), "s.toml")
    }

    /// The error's line (counting the three lines of HEAD), column and message.
    fn error(body: &str) -> (usize, usize, String) {
        crate::testing::error_position(parse(body), body)
    }

    #[test]
    fn a_ramiform_scene_is_its_field_seeded_from_its_limbs() {
        let s = parse(TREE).unwrap();
        assert_eq!(s.continuation.seeds.len(), 3);
        assert!(s.continuation.seeds.iter().all(|&p| s.field.eval(p) < 0.0));
        // A branch's surface one radius (and a little, for its sibling) out; the trunk is
        // thicker than a branch.
        assert!(s.field.eval(DVec3::new(0.1, 0.0, 0.5)) < 0.0);
        assert!(s.field.eval(DVec3::new(0.0, 0.0, 1.0 + 0.0)) < 0.0);
        assert!(s.field.eval(DVec3::new(0.0, 0.6, 0.5)) > 0.0);
        assert!(s.skeleton.is_none());
    }

    /// A chain of `n` limbs, each named and hanging from the one before, the last a leaf.
    fn chain(n: usize) -> String {
        let mut t = String::from("[ramiform]\n");
        for i in 0..n {
            t += &format!("[[ramiform.limb]]\nname = \"l{i}\"\n");
            if i == 0 {
                t += "a = [0, 0, 0]\n";
            } else {
                t += &format!("parent = \"l{}\"\n", i - 1);
            }
            t += &format!("b = [0, {}, {}]\n", (i % 2) as f64 * 0.01, (i + 1) as f64 * 0.01);
            if i + 1 == n {
                t += "radius = 0.005\n";
            }
        }
        t
    }

    #[test]
    fn limb_count_and_depth_are_limited_before_any_work() {
        use skelform_skeleton::ramiform::{MAX_DEPTH, MAX_LIMBS};
        // As deep as allowed is a scene.
        assert!(parse(&chain(MAX_DEPTH)).is_ok());
        // One deeper: refused at the parent of the limb over the limit.
        let text = chain(MAX_DEPTH + 1);
        let (l, c, m) = error(&text);
        let line = text.lines().position(|x| x == format!("parent = \"l{}\"", MAX_DEPTH - 1));
        assert_eq!((l, c), (3 + line.unwrap() + 1, 10), "{m}");
        assert!(
            m.contains(&format!("{} limbs deep, over the limit of {MAX_DEPTH}", MAX_DEPTH + 1)),
            "{m}"
        );
        // Too many limbs (30,000 in a chain ran for minutes): refused at the first one over,
        // in a moment.
        let started = std::time::Instant::now();
        let text = chain(30_000);
        let (l, _, m) = error(&text);
        assert!(m.contains(&format!("30000 limbs, over the limit of {MAX_LIMBS}")), "{m}");
        let line = text.lines().position(|x| x == format!("name = \"l{MAX_LIMBS}\""));
        assert_eq!(l, 3 + line.unwrap() + 3, "{m}");
        assert!(started.elapsed().as_secs() < 10);
        // A wide tree of as many limbs as allowed parses: one root and its leaves.
        let mut wide = String::from(
            "[ramiform]\n[[ramiform.limb]]\nname = \"r\"\na = [0, 0, 0]\nb = [0, 0, 1]\n",
        );
        for i in 1..MAX_LIMBS {
            let a = i as f64 * 0.01;
            wide += &format!(
                "[[ramiform.limb]]\nparent = \"r\"\nb = [{}, {}, 1.5]\nradius = 0.01\n",
                a.cos(),
                a.sin()
            );
        }
        let (_, _, m) = error(&format!(
            "{wide}[[ramiform.limb]]\nparent = \"r\"\nb = [0, 1, 1]\nradius = 0.01\n"
        ));
        assert!(
            m.contains(&format!("{} limbs, over the limit of {MAX_LIMBS}", MAX_LIMBS + 1)),
            "{m}"
        );
        // Radius matching's cost: many directions on a deep chain are refused at `directions`.
        let text = chain(MAX_DEPTH).replace("[ramiform]\n", "[ramiform]\ndirections = 100000\n");
        let (l, c, m) = error(&text);
        assert_eq!((l, c), (5, 14), "{m}");
        assert!(m.contains("limb searches") && m.contains("over the limit"), "{m}");
    }

    #[test]
    fn bad_ramiforms_are_reported_where_they_are() {
        let (l, c, m) =
            error(&TREE.replace("parent = \"trunk\"\nb = [0.4", "parent = \"trnk\"\nb = [0.4"));
        assert_eq!((l, c), (3 + 7, 10), "{m}");
        assert!(m.contains("unknown limb 'trnk'") && m.contains("named so far: trunk"), "{m}");
        let (l, _, m) = error(&TREE.replace("b = [0, 0, 1]\n", "b = [0, 0, 1]\nradius = 0.2\n"));
        assert_eq!(l, 3 + 6, "{m}");
        assert!(m.contains("limb 0 has children"), "{m}");
        let (l, _, m) = error(&TREE.replace("radius = 0.1\n[[", "[["));
        assert_eq!(l, 3 + 8, "{m}");
        assert!(m.contains("limb 1 has no children, so it needs a radius"), "{m}");
        let (_, _, m) = error(&TREE.replace(
            "parent = \"trunk\"\nb = [0.4",
            "parent = \"trunk\"\na = [0, 0, 1]\nb = [0.4",
        ));
        assert!(m.contains("leave 'a' out"), "{m}");
        let (_, _, m) = error(&TREE.replace("a = [0, 0, 0]\n", ""));
        assert!(m.contains("a root limb needs 'a'"), "{m}");
        let (l, _, m) = error(&TREE.replace("radius = 0.1\n[[", "radius = -0.1\n[["));
        assert_eq!(l, 3 + 9, "{m}");
        assert!(m.contains("radius must be a positive length"), "{m}");
        let (_, _, m) = error(&format!("{TREE}[field]\nformula = \"z\"\n"));
        assert!(m.contains("cannot also have [field]"), "{m}");
        let (_, _, m) = error("[ramiform]\n");
        assert!(m.contains("no limbs"), "{m}");
        let (_, _, m) = error(&TREE.replace("[ramiform]\n", "[ramiform]\ndirections = 3\n"));
        assert!(m.contains("directions must be from 8"), "{m}");
    }
}
