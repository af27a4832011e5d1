//! Articulation (DIS §2.3 and ch. 6): a tree of joints, elements attached to joints, and
//! poses that rotate joints so that everything attached downstream moves with them.
//!
//! A joint's frame is its parent's frame, translated by the joint's `offset` (given in the
//! parent's frame) and rotated by its rest rotation followed by the pose's rotation. An element
//! attached to a joint is written in that joint's frame; an element attached to nothing is in
//! world coordinates. [`Articulated::posed`] resolves a pose into a plain [`Skeleton`], so a
//! pose change is a rebuild of the field from new geometry — skeletons are small (the hand
//! has 85 elements) and fields are cheap to build. Rotations, not linear interpolation of
//! endpoints, are what should be interpolated between poses (DIS fig. 2.6): interpolate the
//! quaternions of two [`Pose`]s.

use glam::{DAffine3, DQuat, DVec3};

use crate::SkeletonError;
use crate::skeleton::{Element, Skeleton};

/// A joint, by index into [`Articulated::joints`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct JointId(usize);

impl JointId {
    /// Position of the joint in [`Articulated::joints`]: joints are numbered in the order they
    /// were added, so a parent's index is always below its children's.
    pub fn index(self) -> usize {
        self.0
    }
}

/// A joint: where it sits in its parent's frame, how it is turned at rest, and the axes it
/// turns about.
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    /// Unique within its [`Articulated`]; the name scenes and poses use.
    pub name: String,
    /// The joint whose frame this one is placed in; `None` for a root, placed in world
    /// coordinates.
    pub parent: Option<JointId>,
    /// Position of the joint's origin in its parent's frame (world coordinates for a root), in
    /// scene units. Fixed in that frame, so the joint swings with its parent when the parent
    /// turns.
    pub offset: DVec3,
    /// Rotation of the joint's frame relative to its parent's at rest (unit); a pose's rotation
    /// is applied after it, about the rest frame's axes.
    pub rest: DQuat,
    /// Unit rotation axes in the joint's rest frame, applied in order (intrinsic angles: the
    /// second axis is turned by the first rotation). Empty for a joint that is only turned
    /// by whole rotations ([`Pose::set`]).
    pub axes: Vec<DVec3>,
    /// The angle about each axis (degrees) when a pose does not say otherwise.
    pub default_angles: Vec<f64>,
}

impl Joint {
    /// The rotation (relative to rest) that `degrees` about the joint's axes give:
    /// `R(axis₁, a₁)·R(axis₂, a₂)·…`, so that a finger's first knuckle with axes (palm normal,
    /// side axis) takes the dissertation's Euler angles θ, φ directly (DIS §2.7).
    pub fn rotation(&self, degrees: &[f64]) -> Result<DQuat, SkeletonError> {
        if degrees.len() != self.axes.len() {
            return Err(SkeletonError::AngleCount {
                joint: self.name.clone(),
                axes: self.axes.len(),
                got: degrees.len(),
            });
        }
        if !degrees.iter().all(|a| a.is_finite()) {
            return Err(SkeletonError::NonFinite);
        }
        Ok(self.axes.iter().zip(degrees).fold(DQuat::IDENTITY, |q, (axis, a)| {
            q * DQuat::from_axis_angle(*axis, a.to_radians())
        }))
    }
}

/// A rotation per joint (relative to its rest rotation); joints not set stay at rest.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Pose {
    rotations: Vec<(JointId, DQuat)>,
}

impl Pose {
    /// A pose with no joint set, so every joint at rest. Note that this is not
    /// [`Articulated::default_pose`], which applies the joints' default angles.
    pub fn new() -> Pose {
        Pose::default()
    }

    /// Turns `joint` by `rotation` (replacing an earlier setting for it).
    pub fn set(&mut self, joint: JointId, rotation: DQuat) {
        match self.rotations.iter_mut().find(|(j, _)| *j == joint) {
            Some(r) => r.1 = rotation,
            None => self.rotations.push((joint, rotation)),
        }
    }

    /// The rotation set for `joint` relative to its rest rotation; the identity for a joint the
    /// pose does not set.
    pub fn rotation(&self, joint: JointId) -> DQuat {
        self.rotations.iter().find(|(j, _)| *j == joint).map_or(DQuat::IDENTITY, |(_, q)| *q)
    }

    /// The pose a fraction `t` of the way from `self` to `other`, joint by joint by spherical
    /// interpolation of the rotations.
    pub fn interpolate(&self, other: &Pose, t: f64) -> Pose {
        let mut joints: Vec<JointId> =
            self.rotations.iter().chain(&other.rotations).map(|(j, _)| *j).collect();
        joints.sort_unstable();
        joints.dedup();
        Pose {
            rotations: joints
                .into_iter()
                .map(|j| (j, self.rotation(j).slerp(other.rotation(j), t)))
                .collect(),
        }
    }
}

/// A skeleton whose elements hang from a tree of joints.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Articulated {
    joints: Vec<Joint>,
    /// The elements in their joints' frames, with groups as in a plain skeleton.
    pub skeleton: Skeleton,
    attached: Vec<Option<JointId>>,
}

impl Articulated {
    /// An articulated skeleton with no joints around `skeleton` (whose elements are then
    /// in world coordinates until attached).
    pub fn new(skeleton: Skeleton) -> Articulated {
        let attached = vec![None; skeleton.len()];
        Articulated { joints: Vec::new(), skeleton, attached }
    }

    /// The joints in the order added (parents before children), indexed by [`JointId::index`].
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// Looks a joint up by the name it was added with, as scene files and poses refer to
    /// joints; `None` if no joint has it.
    pub fn joint_named(&self, name: &str) -> Option<JointId> {
        self.joints.iter().position(|j| j.name == name).map(JointId)
    }

    /// Adds a joint under `parent` (or at the root). Parents come before their children, so
    /// the tree has no cycles by construction.
    pub fn add_joint(
        &mut self,
        name: &str,
        parent: Option<JointId>,
        offset: DVec3,
        rest: DQuat,
    ) -> Result<JointId, SkeletonError> {
        if let Some(p) = parent
            && p.0 >= self.joints.len()
        {
            return Err(SkeletonError::UnknownJoint(format!("#{}", p.0)));
        }
        if self.joint_named(name).is_some() {
            return Err(SkeletonError::DuplicateJoint(name.to_string()));
        }
        if !(offset.is_finite() && rest.is_finite()) {
            return Err(SkeletonError::NonFinite);
        }
        self.joints.push(Joint {
            name: name.to_string(),
            parent,
            offset,
            rest: rest.normalize(),
            axes: Vec::new(),
            default_angles: Vec::new(),
        });
        Ok(JointId(self.joints.len() - 1))
    }

    /// Gives `joint` its rotation axes (in its rest frame; normalised here) and the angles
    /// (degrees) it has when a pose does not set it.
    pub fn set_axes(
        &mut self,
        joint: JointId,
        axes: &[DVec3],
        default_degrees: &[f64],
    ) -> Result<(), SkeletonError> {
        let j = self
            .joints
            .get_mut(joint.0)
            .ok_or_else(|| SkeletonError::UnknownJoint(format!("#{}", joint.0)))?;
        if axes.len() != default_degrees.len() {
            return Err(SkeletonError::AngleCount {
                joint: j.name.clone(),
                axes: axes.len(),
                got: default_degrees.len(),
            });
        }
        if !axes.iter().all(|a| a.is_finite() && a.length() > 0.0)
            || !default_degrees.iter().all(|a| a.is_finite())
        {
            return Err(SkeletonError::NonFinite);
        }
        j.axes = axes.iter().map(|a| a.normalize()).collect();
        j.default_angles = default_degrees.to_vec();
        Ok(())
    }

    /// Sets `joint` in `pose` to `degrees` about its axes.
    pub fn set_angles(
        &self,
        pose: &mut Pose,
        joint: JointId,
        degrees: &[f64],
    ) -> Result<(), SkeletonError> {
        let j = self
            .joints
            .get(joint.0)
            .ok_or_else(|| SkeletonError::UnknownJoint(format!("#{}", joint.0)))?;
        pose.set(joint, j.rotation(degrees)?);
        Ok(())
    }

    /// The pose with every joint at its default angles.
    pub fn default_pose(&self) -> Pose {
        let mut pose = Pose::new();
        for (i, j) in self.joints.iter().enumerate() {
            if !j.axes.is_empty() {
                // Axes and defaults were checked together in `set_axes`.
                if let Ok(q) = j.rotation(&j.default_angles) {
                    pose.set(JointId(i), q);
                }
            }
        }
        pose
    }

    /// Attaches element `index` of [`Articulated::skeleton`] to `joint` (its shape is then
    /// read in that joint's frame).
    pub fn attach(&mut self, index: usize, joint: Option<JointId>) -> Result<(), SkeletonError> {
        if let Some(j) = joint
            && j.0 >= self.joints.len()
        {
            return Err(SkeletonError::UnknownJoint(format!("#{}", j.0)));
        }
        if index >= self.skeleton.len() {
            return Err(SkeletonError::UnknownElement(index));
        }
        self.attached.resize(self.skeleton.len(), None);
        self.attached[index] = joint;
        Ok(())
    }

    /// Adds an element written in `joint`'s frame (or in world coordinates for `None`).
    pub fn add(
        &mut self,
        element: Element,
        joint: Option<JointId>,
    ) -> Result<usize, SkeletonError> {
        if let Some(j) = joint
            && j.0 >= self.joints.len()
        {
            return Err(SkeletonError::UnknownJoint(format!("#{}", j.0)));
        }
        let i = self.skeleton.push(element)?;
        self.attached.resize(self.skeleton.len(), None);
        self.attached[i] = joint;
        Ok(i)
    }

    /// Each joint's frame in world coordinates under `pose`.
    pub fn frames(&self, pose: &Pose) -> Vec<DAffine3> {
        let mut out: Vec<DAffine3> = Vec::with_capacity(self.joints.len());
        for (i, j) in self.joints.iter().enumerate() {
            let local =
                DAffine3::from_rotation_translation(j.rest * pose.rotation(JointId(i)), j.offset);
            let parent = j.parent.map_or(DAffine3::IDENTITY, |p| out[p.0]);
            out.push(parent * local);
        }
        out
    }

    /// The plain skeleton in world coordinates under `pose`.
    pub fn posed(&self, pose: &Pose) -> Result<Skeleton, SkeletonError> {
        let frames = self.frames(pose);
        let mut s = self.skeleton.clone();
        s.transform_elements(|i, e| match self.attached.get(i).copied().flatten() {
            Some(j) => e.shape.transformed(&frames[j.0]),
            None => Ok(e.shape.clone()),
        })?;
        Ok(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Segment, Shape};
    use std::f64::consts::FRAC_PI_2;

    /// A two-bone finger: a knuckle at the origin and a middle joint one bone further.
    fn finger() -> (Articulated, JointId, JointId) {
        let mut a = Articulated::new(Skeleton::new());
        let knuckle = a.add_joint("knuckle", None, DVec3::ZERO, DQuat::IDENTITY).unwrap();
        let middle = a.add_joint("middle", Some(knuckle), DVec3::X, DQuat::IDENTITY).unwrap();
        let bone = |len: f64| {
            Element::new(Shape::Segment(Segment::new(DVec3::ZERO, DVec3::X * len).unwrap()), 0.1)
                .unwrap()
        };
        a.add(bone(1.0), Some(knuckle)).unwrap();
        a.add(bone(0.6), Some(middle)).unwrap();
        (a, knuckle, middle)
    }

    fn ends(s: &Skeleton, i: usize) -> (DVec3, DVec3) {
        match &s.elements()[i].shape {
            Shape::Segment(seg) => (seg.a(), seg.b()),
            _ => unreachable!(),
        }
    }

    #[test]
    fn rest_pose_places_bones_end_to_end() {
        let (a, _, _) = finger();
        let s = a.posed(&Pose::new()).unwrap();
        assert_eq!(ends(&s, 0), (DVec3::ZERO, DVec3::X));
        let (p, q) = ends(&s, 1);
        assert!((p - DVec3::X).length() < 1e-15 && (q - DVec3::X * 1.6).length() < 1e-15);
    }

    #[test]
    fn bending_a_joint_moves_everything_after_it() {
        let (a, knuckle, middle) = finger();
        let mut pose = Pose::new();
        pose.set(middle, DQuat::from_rotation_z(FRAC_PI_2));
        let s = a.posed(&pose).unwrap();
        assert_eq!(ends(&s, 0), (DVec3::ZERO, DVec3::X), "the first bone stays");
        let (p, q) = ends(&s, 1);
        assert!(
            (p - DVec3::X).length() < 1e-12 && (q - DVec3::new(1.0, 0.6, 0.0)).length() < 1e-12
        );
        // Turning the knuckle as well carries the middle joint with it.
        pose.set(knuckle, DQuat::from_rotation_z(FRAC_PI_2));
        let s = a.posed(&pose).unwrap();
        let (p, q) = ends(&s, 1);
        assert!(
            (p - DVec3::Y).length() < 1e-12 && (q - DVec3::new(-0.6, 1.0, 0.0)).length() < 1e-12,
            "{p} {q}"
        );
        // Half way between rest and the bent pose, by rotation: the tip stays on its arc.
        let half = Pose::new().interpolate(&pose, 0.5);
        let s = a.posed(&half).unwrap();
        let (_, q) = ends(&s, 0);
        assert!((q.length() - 1.0).abs() < 1e-12, "bones keep their length");
    }

    #[test]
    fn missing_parents_and_duplicates_are_errors() {
        let (mut a, _, _) = finger();
        assert!(matches!(
            a.add_joint("tip", Some(JointId(7)), DVec3::X, DQuat::IDENTITY),
            Err(SkeletonError::UnknownJoint(_))
        ));
        assert!(matches!(
            a.add_joint("middle", None, DVec3::X, DQuat::IDENTITY),
            Err(SkeletonError::DuplicateJoint(_))
        ));
    }

    #[test]
    fn euler_angles_at_a_knuckle_spread_then_bend() {
        // A finger along x with the back of the hand up (+z): θ turns it about z (spread),
        // φ about its own side axis y (bend towards the palm, −z).
        let (mut a, knuckle, middle) = finger();
        a.set_axes(knuckle, &[DVec3::Z, DVec3::Y], &[0.0, 0.0]).unwrap();
        a.set_axes(middle, &[DVec3::Y], &[0.0]).unwrap();
        let mut pose = a.default_pose();
        a.set_angles(&mut pose, knuckle, &[90.0, 90.0]).unwrap();
        let s = a.posed(&pose).unwrap();
        // Spread by 90° the finger points along y; bent by 90° about its side axis it
        // points down.
        let (p, q) = ends(&s, 0);
        assert!(p.length() < 1e-12 && (q + DVec3::Z).length() < 1e-12, "{q}");
        a.set_angles(&mut pose, knuckle, &[30.0, 0.0]).unwrap();
        a.set_angles(&mut pose, middle, &[45.0]).unwrap();
        let s = a.posed(&pose).unwrap();
        let (_, q) = ends(&s, 0);
        let c = 30f64.to_radians();
        assert!((q - DVec3::new(c.cos(), c.sin(), 0.0)).length() < 1e-12, "{q}");
        let (p2, q2) = ends(&s, 1);
        assert!((p2 - q).length() < 1e-12, "the second bone starts where the first ends");
        assert!(((q2 - p2).length() - 0.6).abs() < 1e-12, "and keeps its length");
        assert!(q2.z < -0.4, "bent towards the palm: {q2}");
        // Wrong number of angles.
        assert!(matches!(
            a.set_angles(&mut pose, middle, &[1.0, 2.0]),
            Err(SkeletonError::AngleCount { axes: 1, got: 2, .. })
        ));
        assert!(matches!(
            a.set_axes(middle, &[DVec3::Y], &[]),
            Err(SkeletonError::AngleCount { .. })
        ));
    }

    #[test]
    fn any_pose_keeps_every_bone_length_and_joint_connection() {
        let (mut a, knuckle, middle) = finger();
        a.set_axes(knuckle, &[DVec3::Z, DVec3::Y], &[10.0, 15.0]).unwrap();
        a.set_axes(middle, &[DVec3::Y], &[30.0]).unwrap();
        for k in 0..20 {
            let t = k as f64;
            let mut pose = a.default_pose();
            a.set_angles(&mut pose, knuckle, &[37.0 * t - 200.0, 13.0 * t]).unwrap();
            a.set_angles(&mut pose, middle, &[-90.0 + 11.0 * t]).unwrap();
            let s = a.posed(&pose).unwrap();
            let (p0, q0) = ends(&s, 0);
            let (p1, q1) = ends(&s, 1);
            assert!(((q0 - p0).length() - 1.0).abs() < 1e-12);
            assert!(((q1 - p1).length() - 0.6).abs() < 1e-12);
            assert!((q0 - p1).length() < 1e-12);
        }
    }
}
