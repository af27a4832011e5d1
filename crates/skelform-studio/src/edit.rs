//! The scene as the studio holds it: a `toml_edit` document (so that saving keeps the
//! file's comments and layout), the edits the page sends, and what the page is told about
//! the skeleton.

use serde::Deserialize;
use serde_json::{Value as Json, json};
use skelform::DVec3;
use toml_edit::{Array, DocumentMut, InlineTable, Item, Table, Value};

use crate::StudioError;

/// One step of a path into the document: a key of a table or an index into an array.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum Step {
    /// A key of a table (`"skeleton"`, `"radius"`).
    Key(String),
    /// An index into an array of tables or an array value.
    Index(usize),
}

/// The skeletal element kinds a scene file has, as `[[skeleton.KIND]]` arrays, with the key
/// that holds each kind's points (one point, or a list of them).
pub const ELEMENT_KINDS: &[(&str, &[&str], bool)] = &[
    ("point", &["at"], false),
    ("segment", &["a", "b"], false),
    ("polyline", &["points"], true),
    ("curve", &["bezier"], true),
    ("triangle", &["vertices"], true),
    ("polygon", &["vertices"], true),
];

fn refused(message: impl Into<String>) -> StudioError {
    StudioError::Edit(message.into())
}

fn show(path: &[Step]) -> String {
    let parts: Vec<String> = path
        .iter()
        .map(|s| match s {
            Step::Key(k) => k.clone(),
            Step::Index(i) => i.to_string(),
        })
        .collect();
    parts.join(".")
}

/// A JSON value from the page as a TOML value: numbers stay integers when they are written
/// as integers (as the scene files write them), objects become inline tables. `null` (what
/// a page's NaN or infinity turns into) is refused.
pub fn to_toml(v: &Json) -> Result<Value, StudioError> {
    Ok(match v {
        Json::Null => return Err(refused("not a value (null, NaN or infinity)")),
        Json::Bool(b) => Value::from(*b),
        Json::Number(n) => match (n.as_i64(), n.as_f64()) {
            (Some(i), _) => Value::from(i),
            (None, Some(f)) if f.is_finite() => Value::from(f),
            _ => return Err(refused(format!("{n} is not a finite number"))),
        },
        Json::String(s) => Value::from(s.as_str()),
        Json::Array(items) => {
            let mut a = Array::new();
            for item in items {
                a.push(to_toml(item)?);
            }
            Value::Array(a)
        }
        Json::Object(map) => {
            let mut t = InlineTable::new();
            for (k, item) in map {
                t.insert(k, to_toml(item)?);
            }
            Value::InlineTable(t)
        }
    })
}

/// Replaces `old` with `new`, keeping the whitespace and comment around it.
fn replace_keeping_decor(old: &mut Value, mut new: Value) {
    *new.decor_mut() = old.decor().clone();
    *old = new;
}

/// Sets the value at `path` (creating the last key of a table when it is missing).
pub fn set(doc: &mut DocumentMut, path: &[Step], value: Value) -> Result<(), StudioError> {
    if path.is_empty() {
        return Err(refused("an edit needs a path"));
    }
    set_in_table(doc.as_table_mut(), path, value, path)
}

fn set_in_table(
    t: &mut Table,
    path: &[Step],
    value: Value,
    full: &[Step],
) -> Result<(), StudioError> {
    let Step::Key(k) = &path[0] else {
        return Err(refused(format!("{}: a table has keys, not indices", show(full))));
    };
    if path.len() == 1 {
        match t.get_mut(k) {
            Some(Item::Value(old)) => replace_keeping_decor(old, value),
            Some(_) => return Err(refused(format!("{}: is a table, not a value", show(full)))),
            None => {
                t.insert(k, Item::Value(value));
            }
        }
        return Ok(());
    }
    match t.get_mut(k) {
        Some(item) => set_in_item(item, &path[1..], value, full),
        None => Err(refused(format!("{}: no such key '{k}'", show(full)))),
    }
}

fn set_in_item(
    item: &mut Item,
    path: &[Step],
    value: Value,
    full: &[Step],
) -> Result<(), StudioError> {
    match (item, &path[0]) {
        (Item::Table(t), _) => set_in_table(t, path, value, full),
        (Item::ArrayOfTables(a), Step::Index(i)) => {
            let len = a.len();
            let t = a.get_mut(*i).ok_or_else(|| {
                refused(format!("{}: no element {i} (there are {len})", show(full)))
            })?;
            if path.len() == 1 {
                return Err(refused(format!("{}: is a table, not a value", show(full))));
            }
            set_in_table(t, &path[1..], value, full)
        }
        (Item::Value(v), _) => set_in_value(v, path, value, full),
        _ => Err(refused(format!("{}: no such element", show(full)))),
    }
}

fn set_in_value(
    v: &mut Value,
    path: &[Step],
    value: Value,
    full: &[Step],
) -> Result<(), StudioError> {
    let child = match (v, &path[0]) {
        (Value::Array(a), Step::Index(i)) => {
            let len = a.len();
            a.get_mut(*i).ok_or_else(|| {
                refused(format!("{}: no element {i} (there are {len})", show(full)))
            })?
        }
        (Value::InlineTable(t), Step::Key(k)) => {
            if path.len() == 1 && t.get(k).is_none() {
                t.insert(k, value);
                return Ok(());
            }
            t.get_mut(k).ok_or_else(|| refused(format!("{}: no such key '{k}'", show(full))))?
        }
        _ => return Err(refused(format!("{}: no such element", show(full)))),
    };
    if path.len() == 1 {
        replace_keeping_decor(child, value);
        Ok(())
    } else {
        set_in_value(child, &path[1..], value, full)
    }
}

/// The array of tables `[[skeleton.KIND]]`, created when `create` is set.
fn element_array<'d>(
    doc: &'d mut DocumentMut,
    kind: &str,
    create: bool,
) -> Result<&'d mut toml_edit::ArrayOfTables, StudioError> {
    if !ELEMENT_KINDS.iter().any(|(k, _, _)| *k == kind) {
        let kinds: Vec<&str> = ELEMENT_KINDS.iter().map(|(k, _, _)| *k).collect();
        return Err(refused(format!(
            "unknown element kind '{kind}' (one of {})",
            kinds.join(", ")
        )));
    }
    let root = doc.as_table_mut();
    if !root.contains_key("skeleton") {
        if !create {
            return Err(refused("the scene has no [skeleton]"));
        }
        root.insert("skeleton", Item::Table(Table::new()));
    }
    let Some(Item::Table(skeleton)) = root.get_mut("skeleton") else {
        return Err(refused("[skeleton] is not a table"));
    };
    if !skeleton.contains_key(kind) {
        if !create {
            return Err(refused(format!("the skeleton has no {kind}")));
        }
        skeleton.insert(kind, Item::ArrayOfTables(toml_edit::ArrayOfTables::new()));
    }
    match skeleton.get_mut(kind) {
        Some(Item::ArrayOfTables(a)) => Ok(a),
        _ => Err(refused(format!("skeleton.{kind} is not an array of tables"))),
    }
}

/// Appends an element `[[skeleton.KIND]]` with the keys of `fields`.
pub fn add(doc: &mut DocumentMut, kind: &str, fields: &Json) -> Result<usize, StudioError> {
    let Json::Object(map) = fields else {
        return Err(refused("a new element is given as an object of its keys"));
    };
    let mut t = Table::new();
    for (k, v) in map {
        t.insert(k, Item::Value(to_toml(v)?));
    }
    let a = element_array(doc, kind, true)?;
    a.push(t);
    Ok(a.len() - 1)
}

/// Removes element `index` of `[[skeleton.KIND]]`.
pub fn delete(doc: &mut DocumentMut, kind: &str, index: usize) -> Result<(), StudioError> {
    let a = element_array(doc, kind, false)?;
    if index >= a.len() {
        return Err(refused(format!("no {kind} {index} (there are {})", a.len())));
    }
    a.remove(index);
    Ok(())
}

/// The value at `path`, when there is one.
pub fn get<'d>(doc: &'d DocumentMut, path: &[&str]) -> Option<&'d Item> {
    let mut item = doc.as_item();
    for k in path {
        item = item.get(k)?;
    }
    Some(item)
}

fn number(v: &Value) -> Option<f64> {
    v.as_float().or_else(|| v.as_integer().map(|i| i as f64))
}

fn point(v: &Value) -> Option<DVec3> {
    let a = v.as_array()?;
    if a.len() != 3 {
        return None;
    }
    let c: Vec<f64> = a.iter().filter_map(number).collect();
    (c.len() == 3).then(|| DVec3::new(c[0], c[1], c[2]))
}

/// Numbers of a value that is one number or a list of them.
fn numbers(item: Option<&Item>) -> Vec<f64> {
    match item.and_then(Item::as_value) {
        Some(Value::Array(a)) => a.iter().filter_map(number).collect(),
        Some(v) => number(v).into_iter().collect(),
        None => Vec::new(),
    }
}

fn strings(item: Option<&Item>) -> Vec<String> {
    match item.and_then(Item::as_value) {
        Some(Value::Array(a)) => a.iter().filter_map(|v| v.as_str().map(String::from)).collect(),
        Some(v) => v.as_str().map(String::from).into_iter().collect(),
        None => Vec::new(),
    }
}

fn round(x: f64) -> f64 {
    (x * 1e5).round() / 1e5
}

/// A world position of a handle turned back into the coordinates its element is written in
/// (its joint's frame in the pose shown), rounded to 5 decimals so the file stays readable.
pub fn local_point(
    doc: &DocumentMut,
    scene: &skelform::Scene,
    path: &[Step],
    world: DVec3,
) -> Result<Value, StudioError> {
    let (Some(Step::Key(skeleton)), Some(Step::Key(kind)), Some(Step::Index(i))) =
        (path.first(), path.get(1), path.get(2))
    else {
        return Err(refused(format!("{}: not a point of a skeletal element", show(path))));
    };
    if skeleton != "skeleton" {
        return Err(refused(format!("{}: not a point of a skeletal element", show(path))));
    }
    let joint = get(doc, &["skeleton", kind])
        .and_then(Item::as_array_of_tables)
        .and_then(|a| a.get(*i))
        .and_then(|t| t.get("joint"))
        .and_then(Item::as_str);
    let local = match joint {
        Some(name) => frame(scene, name)
            .ok_or_else(|| refused(format!("no joint '{name}'")))?
            .inverse()
            .transform_point3(world),
        None => world,
    };
    if !local.is_finite() {
        return Err(refused("the point is not finite"));
    }
    let mut a = Array::new();
    for c in [local.x, local.y, local.z] {
        a.push(round(c));
    }
    Ok(Value::Array(a))
}

fn frame(scene: &skelform::Scene, joint: &str) -> Option<glam::DAffine3> {
    let art = scene.articulation.as_ref()?;
    let i = art.joints.iter().position(|j| j == joint)?;
    art.frames.get(i).copied()
}

/// What the page draws of the skeleton: every element with its points in world
/// coordinates (in the pose shown), each point with the document path that holds it (so a
/// dragged handle becomes a `move` edit), and the joints with their angles.
pub fn skeleton_json(doc: &DocumentMut, scene: &skelform::Scene, pose: Option<&str>) -> Json {
    let world = |joint: Option<&str>, p: DVec3| -> DVec3 {
        match joint.and_then(|j| frame(scene, j)) {
            Some(f) => f.transform_point3(p),
            None => p,
        }
    };
    let mut elements = Vec::new();
    for (kind, keys, list) in ELEMENT_KINDS {
        let Some(a) = get(doc, &["skeleton", kind]).and_then(Item::as_array_of_tables) else {
            continue;
        };
        for (i, t) in a.iter().enumerate() {
            let joint = t.get("joint").and_then(Item::as_str);
            let mut points = Vec::new();
            for key in *keys {
                let Some(v) = t.get(key).and_then(Item::as_value) else { continue };
                if *list {
                    for (k, p) in v.as_array().into_iter().flatten().enumerate() {
                        if let Some(p) = point(p) {
                            let w = world(joint, p);
                            points.push(json!({"at": [w.x, w.y, w.z], "path": ["skeleton", kind, i, key, k]}));
                        }
                    }
                } else if let Some(p) = point(v) {
                    let w = world(joint, p);
                    points.push(json!({"at": [w.x, w.y, w.z], "path": ["skeleton", kind, i, key]}));
                }
            }
            let radius = numbers(t.get("radius"));
            let strength = numbers(t.get("strength"));
            elements.push(json!({
                "kind": kind,
                "index": i,
                "points": points,
                "radius": radius,
                "strength": strength,
                "group": t.get("group").and_then(Item::as_str),
                "joint": joint,
            }));
        }
    }
    let pose_table =
        pose.filter(|p| *p != "rest").and_then(|p| get(doc, &["skeleton", "poses", p]));
    let mut joints = Vec::new();
    if let Some(a) = get(doc, &["skeleton", "joint"]).and_then(Item::as_array_of_tables) {
        for (i, t) in a.iter().enumerate() {
            let Some(name) = t.get("name").and_then(Item::as_str) else { continue };
            let angles = match pose_table.and_then(|p| p.get(name)) {
                Some(item) => numbers(Some(item)),
                None => numbers(t.get("angles")),
            };
            let at = frame(scene, name).map(|f| {
                let o = f.transform_point3(DVec3::ZERO);
                [o.x, o.y, o.z]
            });
            joints.push(json!({
                "index": i,
                "name": name,
                "parent": t.get("parent").and_then(Item::as_str),
                "axes": strings(t.get("axes")),
                "angles": angles,
                "at": at,
            }));
        }
    }
    // The skeleton's own settings, which every element shares (a scene file has no
    // per-element kernel or blend).
    let setting = |k: &str| {
        get(doc, &["skeleton", k])
            .and_then(Item::as_value)
            .map(|v| v.to_string().trim().to_string())
    };
    let settings = json!({
        "blend": setting("blend"),
        "kernel": setting("kernel"),
        "radius": setting("radius"),
    });
    json!({"elements": elements, "joints": joints, "settings": settings})
}

/// Where a joint's angles live for the pose shown: its own `angles` in the rest pose, the
/// pose's table entry in a named pose.
pub fn angles_path(
    doc: &DocumentMut,
    joint: &str,
    pose: Option<&str>,
) -> Result<Vec<Step>, StudioError> {
    let joints = get(doc, &["skeleton", "joint"])
        .and_then(Item::as_array_of_tables)
        .ok_or_else(|| refused("the scene has no joints"))?;
    let index = joints
        .iter()
        .position(|t| t.get("name").and_then(Item::as_str) == Some(joint))
        .ok_or_else(|| refused(format!("no joint '{joint}'")))?;
    let key = |s: &str| Step::Key(s.to_string());
    Ok(match pose.filter(|p| *p != "rest") {
        Some(p) => vec![key("skeleton"), key("poses"), key(p), key(joint)],
        None => vec![key("skeleton"), key("joint"), Step::Index(index), key("angles")],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_set_keeps_the_comment_after_the_value_and_a_missing_key_is_added() {
        let mut doc: DocumentMut =
            "[[skeleton.segment]]\na = [0, 0, 0]\nb = [1, 0, 0]\nradius = 0.5   # thick\n"
                .parse()
                .unwrap();
        let path = [Step::Key("skeleton".into()), Step::Key("segment".into()), Step::Index(0)];
        let mut p = path.to_vec();
        p.push(Step::Key("radius".into()));
        set(&mut doc, &p, to_toml(&json!(0.25)).unwrap()).unwrap();
        let mut p = path.to_vec();
        p.push(Step::Key("strength".into()));
        set(&mut doc, &p, to_toml(&json!(2)).unwrap()).unwrap();
        let text = doc.to_string();
        assert!(text.contains("radius = 0.25   # thick"), "{text}");
        assert!(text.contains("strength = 2"), "{text}");
        let mut p = path.to_vec();
        p[2] = Step::Index(3);
        p.push(Step::Key("radius".into()));
        assert!(set(&mut doc, &p, Value::from(1.0)).is_err());
        assert!(to_toml(&Json::Null).is_err());
    }
}
