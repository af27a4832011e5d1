//! Scalar fields for implicit surfaces.
//!
//! A [`Field`] maps a point to a number; its zero set is the surface, **negative inside**.
//! This crate holds the trait and its adapters, the domain box [`Aabb`], regular lattices
//! and sampling ([`grid`]), the scene formula language ([`formula`]), sharp Booleans of two
//! fields ([`combine`]), and progress and cancellation ([`control`]).
//!
//! What it guarantees: evaluation is deterministic and thread-safe (`Field: Send + Sync`),
//! and batch evaluation gives the same numbers as point evaluation. What it does not: a
//! field need not be a distance (values are not Lipschitz-bounded) and may be non-finite at
//! some points; consumers check.
//!
//! ```
//! use skelform_field::{Aabb, Field, formula::Formula, grid::{Grid, sample}, control::Control};
//! use glam::DVec3;
//!
//! let f = Formula::parse("r = sqrt(x^2 + y^2 + z^2)\nr - 1").unwrap();
//! assert!((f.eval(DVec3::new(0.0, 2.0, 0.0)) - 1.0).abs() < 1e-12);
//! let grid = Grid::with_resolution(&Aabb::cube(1.5), 16).unwrap();
//! let volume = sample(&f, &grid, &Control::default()).unwrap();
//! assert_eq!(volume.values.len(), 16 * 16 * 16);
//! ```
#![warn(missing_docs)]

pub mod aabb;
pub mod combine;
pub mod control;
pub mod cpus;
pub mod field;
pub mod formula;
pub mod grid;
pub mod pages;
pub mod region;

pub use aabb::Aabb;
pub use field::{Field, FnField, Iso, LayerSampler, Negate};
pub use glam::DVec3;
pub use region::RegionField;
