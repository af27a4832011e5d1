//! Leaf forms (Bloomenthal, *Skeletal Design of Natural Forms*, chapter 7): a venation
//! skeleton, a blade made from it, veins as convolution surfaces, and the region function
//! that lets the non-manifold polygonizer (chapter 4) make blade and veins as one
//! non-manifold surface.
//!
//! Why a crate of its own: a leaf needs a blade that is a *sheet* (above, below, beyond),
//! which is neither a field nor a skeleton; it combines skeletal convolution
//! (`skelform-skeleton`) with a triangle mesh and answers with regions
//! (`skelform-field::RegionField`), so it sits beside both.
//!
//! Pipeline:
//! 1. [`Venation::maple`]: a palmate venation (a tree of veins in the plane, primaries
//!    clockwise round the petiole, left and right descendants ordered from the base), with
//!    per-point curvature;
//! 2. [`Web`]: the polygonal web (adjacent margin points joined through their vein paths,
//!    the margin smoothed by natural splines), refined by cuts and triangulated by
//!    shortest-diagonal ear cutting; each point wrapped
//!    onto a sphere by its curvature ([`wrap`]) gives the bent [`Blade`];
//! 3. [`Blade::distance`]: the exact signed distance to the blade, with above, below and
//!    beyond, through a bounding-volume hierarchy;
//! 4. [`Veins`]: tapered vein segments summed as a convolution surface;
//! 5. [`BladeRegions`]: the regions beyond (0), vein (1), above (2), below (3), with the
//!    surfaces and curves of interest.
//!
//! Not done (yet): the tertiary venation texture of §7.4 (perturbed subdivision of the cut
//! lines); region gradients for smooth per-pair normals (the polygonizer takes none, so the
//! leaf's normals are area-weighted facet normals); taper along a segment (each segment has
//! one radius, stepping down along a vein, until skeletal tapering lands).
//!
//! ```
//! use skelform_leaf::{Fillet, Leaf, LeafParams, regions};
//! use skelform_field::RegionField;
//! use skelform_skeleton::Kernel;
//! use glam::DVec3;
//! let leaf = Leaf::maple(&LeafParams { curvature: 0.0, ..LeafParams::default() }).unwrap();
//! let r = leaf.regions(Kernel::Wyvill, Fillet::Both).unwrap();
//! // Far above the middle of the flat leaf: above the blade; far out: beyond.
//! assert_eq!(r.region(DVec3::new(0.1, 0.45, 0.2)), regions::ABOVE);
//! assert_eq!(r.region(DVec3::new(0.1, 0.45, -0.2)), regions::BELOW);
//! assert_eq!(r.region(DVec3::new(5.0, 0.0, 0.0)), regions::BEYOND);
//! // On the central primary vein, next to the blade: vein.
//! assert_eq!(r.region(DVec3::new(0.0, 0.5, 0.001)), regions::VEIN);
//! ```
#![warn(missing_docs)]

pub mod blade;
mod error;
pub mod leaf;
pub mod patch;
pub mod regions;
mod rng;
pub mod veins;
pub mod venation;
pub mod web;

pub use blade::{Blade, BladeDistance, Side};
pub use error::LeafError;
pub use leaf::{Leaf, VeinCurve};
pub use patch::{BicubicPatch, PatchBlend};
pub use regions::{BladeRegions, Fillet, VeinRule};
pub use veins::{VeinSegment, Veins};
pub use venation::{LeafParams, Vein, VeinKind, Venation, wrap};
pub use web::{Web, WebStats};
