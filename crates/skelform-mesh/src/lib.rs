//! Indexed triangle meshes: the type, readers and writers, and a topology checker.
//!
//! Guarantees: writers are atomic (a temporary file in the target directory, renamed into
//! place; removed on `SIGINT`, `SIGTERM` and `SIGHUP` too), so a failed or interrupted write
//! never leaves a partial file; a replaced file keeps its permissions; readers never panic on
//! malformed input, say where it is malformed, and refuse files that would expand beyond
//! [`io::limits`] before allocating for them. Not guaranteed: a mesh read from elsewhere is
//! not repaired; the checker reports what it finds (open edges, non-manifold edges, flipped
//! faces, degenerate and duplicate faces) and changes nothing.
//!
//! What each format keeps (details in each module of [`io`]):
//!
//! | format | positions, triangles | normals | labels | curves | read by others |
//! |---|---|---|---|---|---|
//! | PLY | exact (`f32`, indices kept) | yes | `region_a`/`region_b` per face, with palette colours | `OUT.curves.ply` beside it (default), inline, or none | trimesh, meshio (labels: ASCII only), pymeshlab, MeshLab, Open3D |
//! | OBJ | exact (shortest round-trip text), faces grouped by label | yes, when one per vertex | groups `region_A_B`, colours in `OUT.mtl` | `l` lines | trimesh, meshio, pymeshlab |
//! | STL | triangle soup, welded on reading | no | no | no | everyone |
//! | glTF binary | one primitive per label, vertices not shared between labels | yes (oriented to the winding) | per primitive (`extras`), palette materials | line primitives with a material, optional | trimesh, Blender, three.js; pymeshlab without curves |
//!
//! A mesh's texture image ([`Texture`], the leaf's venation) goes into the glb as PNG (the
//! surfaces' base colour texture, read back) and beside a labelled OBJ as
//! `OUT.texture.png` (every region's `map_Kd`); PLY and STL have no place for it.
//!
//! PLY, OBJ and glTF of one mesh read back to the same topology (`check` finds the same
//! components); STL, having no indices, joins sheets that meet along a curve.
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

pub use mesh::{CurveEdge, Mesh, MeshError, RegionPair, RegionTriple, Texture};
