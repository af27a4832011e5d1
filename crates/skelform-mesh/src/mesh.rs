//! The indexed triangle mesh that every polygonizer produces and every writer consumes.

use serde::{Deserialize, Serialize};

/// The unordered pair of regions a surface separates, stored with `0 < 1`.
///
/// A triangle labelled `(a, b)` is wound counter-clockwise seen from region `a`, the lesser,
/// so its right-hand normal points into `a` (the non-manifold polygonizer's surfaces, checked
/// in its tests: a sphere's region inside, the default region outside, normals inward when
/// the sphere's id is the lesser). A plain manifold surface, whose triangles are
/// counter-clockwise seen from outside ([`Mesh::triangles`]), is `RegionPair(0, 1)` when a
/// label is needed: region 0 outside, region 1 inside (`f < 0`), so that the two rules agree.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct RegionPair(pub u32, pub u32);

impl RegionPair {
    /// The pair of `a` and `b` in either order. `a == b` is not a surface; callers check.
    pub fn new(a: u32, b: u32) -> Self {
        if a <= b { RegionPair(a, b) } else { RegionPair(b, a) }
    }
}

impl std::fmt::Display for RegionPair {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}_{}", self.0, self.1)
    }
}

/// Three regions meeting along a curve, stored sorted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct RegionTriple(pub [u32; 3]);

impl RegionTriple {
    /// The triple of three region ids in any order, sorted so that equal triples compare
    /// equal. The ids should be distinct (a curve separates three regions); not checked.
    pub fn new(mut r: [u32; 3]) -> Self {
        r.sort_unstable();
        RegionTriple(r)
    }
}

impl std::fmt::Display for RegionTriple {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}_{}_{}", self.0[0], self.0[1], self.0[2])
    }
}

/// One segment of a labelled curve (an intersection or self-intersection curve).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct CurveEdge {
    /// The segment's two ends, as indices into [`Mesh::positions`]; the segments of one
    /// polyline meet at shared indices (the checker's `open_ends` counts the vertices where
    /// an odd number of a label's segments end).
    pub v: [u32; 2],
    /// The three regions meeting along the curve (the three sheets the curve borders).
    pub label: RegionTriple,
}

/// Indexed triangles with optional per-vertex normals, colours and texture coordinates,
/// per-face labels and curves.
///
/// Invariants (checked by [`Mesh::validate`]): every index is in range; `normals`,
/// `colors` and `uvs` are each empty or as long as `positions`; `labels` is empty or as long as
/// `triangles`; a texture has the size it says ([`Texture::validate`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions in scene units, as `f32`: the polygonizers evaluate fields and place
    /// vertices in `f64` and round once when storing them here.
    pub positions: Vec<[f32; 3]>,
    /// Unit outward normals, one per vertex, or empty.
    pub normals: Vec<[f32; 3]>,
    /// Counter-clockwise seen from outside (an unlabelled mesh), or from the lesser region of
    /// the triangle's label (see [`RegionPair`]).
    pub triangles: Vec<[u32; 3]>,
    /// One label per triangle, or empty for an unlabelled mesh.
    pub labels: Vec<RegionPair>,
    /// Curve segments (polylines as edges), or empty.
    pub curves: Vec<CurveEdge>,
    /// sRGB colours in `[0, 1]` (as displayed), one per vertex, or empty: a skeleton's element
    /// colours blended at each vertex (DIS ch. 6), written to PLY and glb and drawn by the
    /// renderer.
    pub colors: Vec<[f32; 3]>,
    /// Texture coordinates `[u, v]`, one per vertex, or empty: for a scene with sweeps, the
    /// sweep's arc-length fraction and angle fraction (DIS §5.7), written to glb
    /// (`TEXCOORD_0`), OBJ (`vt`) and PLY (`u`, `v`). Per vertex, so a triangle across a
    /// sweep's seam (`v` = 0 = 1) interpolates backwards across the whole range.
    pub uvs: Vec<[f32; 2]>,
    /// An image to sample at [`Mesh::uvs`], or `None`: the leaf's tertiary venation (§7.4).
    /// Where a mesh has both a texture and texture coordinates, the texture is its colour
    /// (the glb writer embeds it as the base colour texture, the renderer samples it per
    /// pixel); [`Mesh::colors`] then serve only the formats that carry no image (PLY).
    /// Shared, so that cloning a mesh does not copy the image.
    pub texture: Option<std::sync::Arc<Texture>>,
}

/// An RGBA image (8 bits a channel, sRGB colour, straight alpha), rows from the top: texel
/// `(x, y)` is at `rgba[4 * (y * width + x)..][..4]` and covers `u` in
/// `[x / width, (x + 1) / width]`, `v` in `[y / height, (y + 1) / height]`, glTF's
/// convention (`v` runs down the image). Format-neutral: writers decide how to store it.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Texture {
    /// Width in texels (more than 0).
    pub width: u32,
    /// Height in texels (more than 0).
    pub height: u32,
    /// `width × height × 4` bytes.
    pub rgba: Vec<u8>,
}

impl Texture {
    /// The most texels along a side a texture may have: 8192 (256 MiB of RGBA at most),
    /// beyond any use here and within what viewers load.
    pub const MAX_SIDE: u32 = 8192;

    /// The texel at column `x`, row `y`, or `None` outside the image.
    pub fn texel(&self, x: u32, y: u32) -> Option<[u8; 4]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let at = 4 * (y as usize * self.width as usize + x as usize);
        self.rgba.get(at..at + 4).and_then(|s| s.try_into().ok())
    }

    /// Checks the size: both sides from 1 to [`Texture::MAX_SIDE`] and four bytes a texel.
    pub fn validate(&self) -> Result<(), MeshError> {
        let expected =
            (self.width as usize).checked_mul(self.height as usize).and_then(|n| n.checked_mul(4));
        let sides = (1..=Texture::MAX_SIDE).contains(&self.width)
            && (1..=Texture::MAX_SIDE).contains(&self.height);
        if !sides || expected != Some(self.rgba.len()) {
            return Err(MeshError::TextureSize {
                width: self.width,
                height: self.height,
                bytes: self.rgba.len(),
            });
        }
        Ok(())
    }
}

/// What is wrong with a mesh that breaks the [`Mesh`] invariants.
#[derive(Debug, thiserror::Error, Clone, PartialEq, Eq)]
pub enum MeshError {
    #[error("triangle {face} uses vertex {index}, but there are only {vertices} vertices")]
    /// A triangle refers to a vertex that does not exist.
    IndexOutOfRange {
        /// Index of the triangle in [`Mesh::triangles`].
        face: usize,
        /// The offending vertex index.
        index: u32,
        /// Length of [`Mesh::positions`].
        vertices: usize,
    },
    #[error("curve edge {edge} uses vertex {index}, but there are only {vertices} vertices")]
    /// A curve segment refers to a vertex that does not exist.
    CurveIndexOutOfRange {
        /// Index of the segment in [`Mesh::curves`].
        edge: usize,
        /// The offending vertex index.
        index: u32,
        /// Length of [`Mesh::positions`].
        vertices: usize,
    },
    #[error("{normals} normals for {vertices} vertices")]
    /// Normals are present but not one per vertex.
    NormalCount {
        /// Length of [`Mesh::normals`].
        normals: usize,
        /// Length of [`Mesh::positions`].
        vertices: usize,
    },
    #[error("{colors} colours for {vertices} vertices")]
    /// Colours are present but not one per vertex.
    ColorCount {
        /// Length of [`Mesh::colors`].
        colors: usize,
        /// Length of [`Mesh::positions`].
        vertices: usize,
    },
    #[error("{uvs} texture coordinates for {vertices} vertices")]
    /// Texture coordinates are present but not one per vertex.
    UvCount {
        /// Length of [`Mesh::uvs`].
        uvs: usize,
        /// Length of [`Mesh::positions`].
        vertices: usize,
    },
    #[error(
        "a texture of {width} x {height} texels with {bytes} bytes (sides must be 1 to 8192, \
         4 bytes a texel)"
    )]
    /// The texture's sides are out of range or its bytes are not four per texel.
    TextureSize {
        /// [`Texture::width`].
        width: u32,
        /// [`Texture::height`].
        height: u32,
        /// Length of [`Texture::rgba`].
        bytes: usize,
    },
    #[error("{labels} labels for {triangles} triangles")]
    /// Labels are present but not one per triangle.
    LabelCount {
        /// Length of [`Mesh::labels`].
        labels: usize,
        /// Length of [`Mesh::triangles`].
        triangles: usize,
    },
}

impl Mesh {
    /// Length of [`Mesh::positions`], vertices used by no triangle (curve-only or
    /// unreferenced ones) included.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Length of [`Mesh::triangles`], degenerate and duplicate triangles included.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Whether the mesh has no triangles, so no surface to write or draw; vertices and
    /// curves alone do not make it non-empty.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Checks the invariants listed on [`Mesh`].
    pub fn validate(&self) -> Result<(), MeshError> {
        let n = self.positions.len();
        if !self.normals.is_empty() && self.normals.len() != n {
            return Err(MeshError::NormalCount { normals: self.normals.len(), vertices: n });
        }
        if !self.colors.is_empty() && self.colors.len() != n {
            return Err(MeshError::ColorCount { colors: self.colors.len(), vertices: n });
        }
        if !self.uvs.is_empty() && self.uvs.len() != n {
            return Err(MeshError::UvCount { uvs: self.uvs.len(), vertices: n });
        }
        if let Some(t) = &self.texture {
            t.validate()?;
        }
        if !self.labels.is_empty() && self.labels.len() != self.triangles.len() {
            return Err(MeshError::LabelCount {
                labels: self.labels.len(),
                triangles: self.triangles.len(),
            });
        }
        // The largest index first, a reduction the compiler vectorizes (a fraction of a
        // millisecond for a million triangles, where the search below, which stops at the
        // first bad corner, is several times slower); the search runs only to name the
        // first bad triangle of a mesh that has one.
        let largest = self.triangles.iter().flatten().fold(0, |m, &i| m.max(i));
        if !self.triangles.is_empty() && largest as usize >= n {
            for (face, t) in self.triangles.iter().enumerate() {
                if let Some(&index) = t.iter().find(|&&i| i as usize >= n) {
                    return Err(MeshError::IndexOutOfRange { face, index, vertices: n });
                }
            }
        }
        for (edge, c) in self.curves.iter().enumerate() {
            if let Some(&index) = c.v.iter().find(|&&i| i as usize >= n) {
                return Err(MeshError::CurveIndexOutOfRange { edge, index, vertices: n });
            }
        }
        Ok(())
    }

    /// The smallest box holding every vertex, or `None` for a mesh without vertices.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let first = *self.positions.first()?;
        Some(self.positions.iter().fold((first, first), |(lo, hi), p| {
            (
                [lo[0].min(p[0]), lo[1].min(p[1]), lo[2].min(p[2])],
                [hi[0].max(p[0]), hi[1].max(p[1]), hi[2].max(p[2])],
            )
        }))
    }

    /// The distinct labels, sorted, with their triangle counts.
    pub fn label_counts(&self) -> Vec<(RegionPair, usize)> {
        let mut counts = std::collections::BTreeMap::new();
        for l in &self.labels {
            *counts.entry(*l).or_insert(0) += 1;
        }
        counts.into_iter().collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validate_catches_bad_indices_and_counts() {
        let mut m = Mesh {
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2]],
            ..Mesh::default()
        };
        assert_eq!(m.validate(), Ok(()));
        m.triangles.push([0, 1, 3]);
        assert_eq!(
            m.validate(),
            Err(MeshError::IndexOutOfRange { face: 1, index: 3, vertices: 3 })
        );
        // The first bad triangle is named, whichever corner is bad and however large the
        // indices of later ones.
        m.triangles = vec![[0, 1, 2]; 12];
        m.triangles[9] = [u32::MAX, 0, 1];
        m.triangles[5] = [2, 1, 4];
        assert_eq!(
            m.validate(),
            Err(MeshError::IndexOutOfRange { face: 5, index: 4, vertices: 3 })
        );
        m.triangles.truncate(1);
        let empty = Mesh { triangles: vec![[0, 0, 0]], ..Mesh::default() };
        assert_eq!(
            empty.validate(),
            Err(MeshError::IndexOutOfRange { face: 0, index: 0, vertices: 0 })
        );
        m.labels = vec![RegionPair::new(2, 1), RegionPair(0, 1)];
        assert!(matches!(m.validate(), Err(MeshError::LabelCount { .. })));
        m.labels.clear();
        m.colors = vec![[1.0, 0.0, 0.0]; 2];
        assert_eq!(m.validate(), Err(MeshError::ColorCount { colors: 2, vertices: 3 }));
        m.colors.clear();
        m.uvs = vec![[0.0, 1.0]; 4];
        assert_eq!(m.validate(), Err(MeshError::UvCount { uvs: 4, vertices: 3 }));
        m.uvs.clear();
        m.texture = Some(std::sync::Arc::new(Texture { width: 2, height: 2, rgba: vec![0; 16] }));
        assert_eq!(m.validate(), Ok(()));
        assert_eq!(m.texture.as_ref().unwrap().texel(1, 1), Some([0; 4]));
        assert_eq!(m.texture.as_ref().unwrap().texel(2, 0), None);
        m.texture = Some(std::sync::Arc::new(Texture { width: 2, height: 2, rgba: vec![0; 15] }));
        assert!(matches!(m.validate(), Err(MeshError::TextureSize { bytes: 15, .. })));
        m.texture = Some(std::sync::Arc::new(Texture { width: 0, height: 2, rgba: Vec::new() }));
        assert!(matches!(m.validate(), Err(MeshError::TextureSize { width: 0, .. })));
        m.texture = None;
        assert_eq!(RegionPair::new(2, 1), RegionPair(1, 2));
        assert_eq!(RegionTriple::new([3, 1, 2]).to_string(), "1_2_3");
    }
}
