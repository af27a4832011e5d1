//! Skeletal primitives and the fields built on them (Bloomenthal, *Skeletal Design of
//! Natural Forms*, chapters 5 and 6).
//!
//! A [`Skeleton`] is a list of elements — points, segments (polylines and cubic curves become
//! chains of segments) and planar polygons — each with a radius, a strength and a blend
//! group. A [`SkeletonField`] turns it into a [`skelform_field::Field`] under one [`Blend`]:
//! a convolution surface with one of the [`Kernel`]s, a sum of kernels of distances, a union
//! of distance surfaces, Rockwood's (super-)elliptic blend, or the combination surface.
//!
//! What it guarantees:
//! * the field convention of the workspace: **inside negative**, outward normal `∇f/|∇f|`; a
//!   density `D` with iso value `c` is exposed as `c − D`;
//! * radius means radius: a lone point, a long segment and a large polygon of radius `r` have
//!   their surface at distance `r` from the skeleton, for every kernel and blend (the
//!   dissertation's normalisation, eq. 5.30–5.32, extended to the other kernels);
//! * convolution is exact — closed forms for points and segments and, with the Wyvill and
//!   triweight kernels, for polygons; adaptive quadrature (agreeing with an independent
//!   reference to better than 10⁻⁶, tested) for polygons under the Gaussian and B-spline —
//!   and superposition holds: a polyline's field is exactly the sum of its segments';
//! * gradients are analytic (polygons: exact up to the same quadrature tolerance);
//! * evaluation is deterministic, and a batch gives bit-for-bit the values of single points;
//! * every element contributes nothing outside its box (the Gaussian is cut where it falls
//!   below 2⁻⁴⁰); elements outside a point's reach cost one box test.
//!
//! Articulation: an [`Articulated`] skeleton hangs elements from a tree of joints; a [`Pose`]
//! rotates joints and [`Articulated::posed`] gives the plain skeleton to build a field from.
//!
//! Joints turn about named axes by angles in degrees ([`Articulated::set_axes`],
//! [`Articulated::set_angles`]), so the dissertation's finger parameters (θ, φ at the first
//! knuckle, grip2 and grip3 at the others) are joint angles as they stand; the scene syntax
//! is `[[skeleton.joint]]` and `[skeleton.poses.NAME]` (`docs/SCENES.md`).
//!
//! What it does not (yet): tapered radii, the joint combination
//! surface of appendix A.2 with per-joint planes, the raster-image polygon method of appendix
//! A.3, a closed form for polygons under the Gaussian and B-spline kernels (they use adaptive
//! quadrature); distance surfaces take the distance to the skeleton element, so they
//! crease where the skeleton is concave (§5.5.2), as the dissertation describes.
//!
//! ```
//! use skelform_skeleton::{Blend, GroupId, Kernel, Skeleton, SkeletonField};
//! use skelform_field::Field;
//! use glam::DVec3;
//!
//! // A tee of two segments, radius 0.1, as a Gaussian convolution surface.
//! let mut s = Skeleton::new();
//! let g = GroupId::DEFAULT;
//! s.add_segment(DVec3::new(-1.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0), 0.1, g).unwrap();
//! s.add_segment(DVec3::ZERO, DVec3::new(0.0, 0.5, 0.0), 0.1, g).unwrap();
//! let f = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
//! // Far along the bar, one radius from it, the field is zero: the surface.
//! assert!(f.eval(DVec3::new(-0.5, 0.0, 0.1)).abs() < 1e-6);
//! // Above the junction the densities add up to ¾ (DIS §5.6.14): the tee bulges there.
//! assert!((f.eval(DVec3::new(0.0, 0.0, 0.1)) - (0.5 - 0.75)).abs() < 1e-6);
//! assert_eq!(f.seed_points().len(), 2);
//! ```

pub mod convolution;
pub mod curve;
mod error;
pub mod field;
pub mod geometry;
pub mod kernel;
pub mod pose;
mod quad;
pub mod skeleton;

pub use curve::{CubicCurve, Frame};
pub use error::SkeletonError;
pub use field::{Blend, DEFAULT_ISO, Falloff, SkeletonField};
pub use geometry::{Polygon, Segment, Shape};
pub use kernel::Kernel;
pub use pose::{Articulated, Joint, JointId, Pose};
pub use skeleton::{Element, Group, GroupId, Skeleton};
