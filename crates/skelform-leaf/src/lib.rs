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
//!    shortest-diagonal ear cutting (with the default limits, 474 triangles for 113 venation
//!    points, as the dissertation's 475 for 117, fig. 7.8); each point wrapped onto a sphere
//!    by its curvature ([`wrap`]) gives the bent [`Blade`];
//! 3. [`Blade::distance`]: the exact signed distance to the blade, with above, below and
//!    beyond, through a bounding-volume hierarchy;
//! 4. [`Veins`]: tapered vein segments (primaries, and secondaries with a positive
//!    `secondary_radius`) summed as a convolution surface;
//! 5. [`BladeRegions`]: the regions beyond (0), vein (1), above (2), below (3), with the
//!    surfaces and curves of interest, the dissertation's vein rule `Σ > |d|/r` (or the
//!    capped one that keeps petioles, [`VeinRule`]), and gradients for smooth normals (the
//!    blade's plane, `Σ − |d|/r` for the veins);
//! 6. [`texture`]: the tertiary venation texture of §7.4 (fig. 7.14), the web's cuts
//!    subdivided again with perturbed midpoints (seeded), as colours at points of the leaf.
//!
//! Guarantees: the web tiles the blade (areas add up, no T-junctions, veins on blade
//! edges); blade distances equal a brute-force search bit for bit; a leaf, its mesh and its
//! texture are the same for the same parameters on any run and thread count; tertiary lines
//! lie inside the blade and stray from their cut by at most `roughness·L / (1 − q)`.
//!
//! Not done: taper along a segment (each segment has one radius, stepping down along a vein);
//! texture filtering is left to whoever draws the image (no mipmaps are made here).
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
pub mod texture;
pub mod veins;
pub mod venation;
pub mod web;

pub use blade::{Blade, BladeDistance, Side};
pub use error::LeafError;
pub use leaf::{Leaf, VeinCurve};
pub use patch::{BicubicPatch, PatchBlend};
pub use regions::{BladeRegions, Fillet, VeinRule};
pub use texture::{LeafTexture, TertiaryVenation, TextureParams};
pub use veins::{VeinSegment, Veins};
pub use venation::{LeafParams, Vein, VeinKind, Venation, wrap};
pub use web::{Web, WebStats};
