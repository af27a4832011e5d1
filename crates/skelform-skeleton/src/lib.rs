//! Skeletal primitives and the fields built on them (Bloomenthal, *Skeletal Design of
//! Natural Forms*, chapters 5 and 6).
//!
//! A [`Skeleton`] is a list of elements — points, segments (polylines and cubic curves become
//! chains of segments) and planar polygons — each with a radius, a strength and a blend
//! group. A [`SkeletonField`] turns it into a [`skelform_field::Field`] under one [`Blend`]:
//! a convolution surface with one of the [`Kernel`]s, a sum of kernels of distances, a union
//! of distance surfaces, Rockwood's (super-)elliptic blend, or the combination surface.
//!
//! The kernels are the Gaussian and those the dissertation compares it with (§5.6.7–5.6.9,
//! fig. 5.54): Wyvill's, the triweight, the cubic B-spline and the sinc. The sinc is there to
//! show why it was rejected — it is not monotone, so a row of sources grows a spurious contour
//! (fig. 5.49, measured in the tests: a second, hollow band 3.3–4.2 radii out) — and it
//! convolves points only (a point's convolution is the kernel itself); under the sum blend it
//! takes every element.
//!
//! What it guarantees:
//! * the field convention of the workspace: **inside negative**, outward normal `∇f/|∇f|`; a
//!   density `D` with iso value `c` is exposed as `c − D`;
//! * radius means radius: a lone point, a long segment and a large polygon of radius `r` have
//!   their surface at distance `r` from the skeleton, for every kernel and blend (the
//!   dissertation's normalisation, eq. 5.30–5.32, extended to the other kernels; for the
//!   sinc under convolution, points only, and a lone point has no second contour); a tapered
//!   segment has, away from its ends, the radius interpolated along it (within 2 %, tested);
//! * convolution is exact — closed forms for points and segments and, with the Wyvill and
//!   triweight kernels, for polygons; for polygons under the Gaussian a closed form up to a
//!   fixed 20-point rule per edge ([`gauss_edge`], agreeing with adaptive quadrature to
//!   2·10⁻¹² relative, 8.7× faster); adaptive quadrature for the B-spline (agreeing with
//!   an independent reference to better than 10⁻⁶, tested) — and superposition holds: a
//!   polyline's field is exactly the sum of its segments', tapered or not;
//! * gradients are analytic (polygons: exact up to the same quadrature tolerance), except
//!   near a junction, where they are central differences of the junction's density (the
//!   joint combination surface involves the convolution's Hessian);
//! * evaluation is deterministic, and a batch gives bit-for-bit the values of single points;
//! * every element contributes nothing outside its box (the Gaussian is cut where it falls
//!   below 2⁻⁴⁰, the sinc at its third zero, 4.97 radii); elements outside a point's reach
//!   cost one box test.
//!
//! Blend control beyond groups: [`Skeleton::add_junction`] blends the limbs meeting at a
//! joint by the joint combination surface of DIS eq. 5.37 and appendix A.2 ([`junction`]),
//! removing the convolution's bulge over the joint (1.26 r → 1.02 r over a tee); the chains
//! continuing from the limbs belong to the junction, and the branch points of one tree make
//! one junction with several joints; `Blend::SuperElliptic { angle_scaled }`
//! is eq. 5.14, which removes the super-elliptic blend's bulge where primitives cross.
//! Chapter 6's controls: a polygon's strength may vary over it by per-vertex weights
//! ([`Element::with_vertex_weights`], integrated exactly: [`weights`],
//! [`convolution::convolve_weighted`]) or a weight image ([`Element::with_weight_image`],
//! through the image method), DIS §6.4; segments may be convolved by the dissertation's
//! separable approximation for comparison ([`SkeletonField::with_separable_segments`],
//! figs. 5.52/5.53).
//! Polygons may use the dissertation's raster-image method instead of the exact integral
//! ([`PolygonMethod::Image`], appendix A.3), for comparison.
//!
//! Branching: a [`Ramiform`] is a tree of limbs whose field is the recursive
//! `max(f_parent, Σ f_children)` of DIS eqs. 3.3 and 5.36, each parent's radius matched to
//! its children's at the joint plane ([`ramiform`]).
//!
//! Articulation: an [`Articulated`] skeleton hangs elements from a tree of joints; a [`Pose`]
//! rotates joints and [`Articulated::posed`] gives the plain skeleton to build a field from.
//!
//! Joints turn about named axes by angles in degrees ([`Articulated::set_axes`],
//! [`Articulated::set_angles`]), so the dissertation's finger parameters (θ, φ at the first
//! knuckle, grip2 and grip3 at the others) are joint angles as they stand; the scene syntax
//! is `[[skeleton.joint]]` and `[skeleton.poses.NAME]` (`docs/SCENES.md`).
//!
//! What it does not (yet): a closed form for polygons under the B-spline kernel (adaptive
//! quadrature); segments and polygons convolved with the sinc (refused with
//! [`SkeletonError::KernelConvolvesPointsOnly`]: no closed form, and its plane integral does
//! not converge; [`convolution::convolve`] answers for them by quadrature of the truncated
//! kernel); per-vertex radii on polygons (segments, polylines and curves taper);
//! several convexity directions per joint (the `max_i(v·d_i)` of §5.6.14.5: one direction,
//! user-set or the joint's plane normal). The appendix's blended normals near junctions
//! are an option ([`SkeletonField::with_blended_normals`]); by default the gradient of the
//! combined field is used, so the crease that the union leaves between limbs out of the
//! joint's plane shows in shading, as the dissertation reports. The angle-scaled super-elliptic
//! blend takes its angle from the two elements nearest the point, so with three or more
//! elements in range it can jump where the second and third nearest swap. The image method
//! is exact only for the separable Gaussian (for the other kernels it is the dissertation's
//! separable approximation). Distance surfaces take the distance to the skeleton element,
//! so they crease where the skeleton is concave (§5.5.2), as the dissertation describes.
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
#![warn(missing_docs)]

pub mod convolution;
pub mod curve;
mod error;
pub mod field;
pub mod gauss_edge;
pub mod geometry;
pub mod image;
pub mod junction;
pub mod kernel;
pub mod pose;
mod quad;
pub mod ramiform;
pub mod skeleton;
pub mod sweep;
pub mod weights;

pub use curve::{CubicCurve, Frame};
pub use error::SkeletonError;
pub use field::{Blend, DEFAULT_ISO, Falloff, GlobalChange, NEUTRAL_COLOR, SkeletonField};
pub use geometry::{Polygon, Segment, Shape};
pub use image::{
    DEFAULT_IMAGE_RESOLUTION, MAX_IMAGE_BYTES, MAX_IMAGE_RESOLUTION, MAX_IMAGE_WORK, PolygonMethod,
};
pub use kernel::Kernel;
pub use pose::{Articulated, Joint, JointId, Pose};
pub use ramiform::{Limb, Ramiform, RamiformField, RamiformOptions};
pub use skeleton::{Element, Group, GroupId, Junction, JunctionJoint, Skeleton, check_color};
pub use sweep::{Sweep, SweepSettings, SweptField};
pub use weights::WeightImage;
