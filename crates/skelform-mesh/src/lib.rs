//! Indexed triangle meshes: the type, readers and writers, and a topology checker.
//!
//! Guarantees: writers are atomic (a temporary file in the target directory, renamed into
//! place), so a failed write never leaves a partial file; readers never panic on malformed
//! input and say where it is malformed. Not guaranteed: a mesh read from elsewhere is not
//! repaired; the checker reports what it finds (open edges, non-manifold edges, flipped
//! faces, degenerate and duplicate faces) and changes nothing.
//!
//! ```
//! use skelform_mesh::{Mesh, check::check};
//! // A tetrahedron, wound outward.
//! let m = Mesh {
//!     positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
//!     triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
//!     ..Mesh::default()
//! };
//! let report = check(&m);
//! assert!(report.is_closed_manifold());
//! assert_eq!(report.components[0].genus, Some(0));
//! ```
#![warn(missing_docs)]

pub mod check;
pub mod io;
pub mod mesh;
pub mod palette;

pub use mesh::{CurveEdge, Mesh, MeshError, RegionPair, RegionTriple};
