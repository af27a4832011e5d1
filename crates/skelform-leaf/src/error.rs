//! What can be wrong with a leaf.

/// A leaf that cannot be built, and why. Messages name the value, so that a scene loader can
/// add the file position and pass them on unchanged.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LeafError {
    #[error("{name} must be {expected} (got {value})")]
    /// A [`LeafParams`](crate::LeafParams) value out of its range.
    BadParameter {
        /// The name of the `LeafParams` field.
        name: &'static str,
        /// The value given.
        value: f64,
        /// The accepted range, in words ("a length of 0 or more").
        expected: &'static str,
    },
    #[error("the blade outline needs at least 3 points (got {0})")]
    /// A flat outline ([`Leaf::from_outline`](crate::Leaf::from_outline)) with fewer than
    /// three points; the value is the count given.
    TooFewPoints(usize),
    /// A flat outline that encloses no area or is not simple, so it cannot be cut into
    /// counter-clockwise polygons.
    #[error("the blade outline has zero area or crosses itself")]
    BadOutline,
    #[error("vein {vein} {why}")]
    /// An explicit vein that cannot become convolution segments.
    BadVein {
        /// Index of the vein in the list given.
        vein: usize,
        /// What is wrong with it, as a phrase following "vein N": fewer than two points,
        /// points and radii of different counts, a radius that is not positive, or a
        /// repeated point.
        why: String,
    },
    #[error("the venation's polygonal web does not tile the blade: {0}")]
    /// The venation's polygonal web (§7.2) does not tile the blade: the margin or a web
    /// polygon crosses itself (veins that cross), a polygon has no area, or the polygons'
    /// areas do not add up to the margin's. Generated venations whose parameters make veins
    /// cross end here.
    BadWeb(String),
    #[error("cannot triangulate web polygon {0}: no ear is free of other vertices")]
    /// Ear cutting found no ear in the web polygon with this index (every candidate contains
    /// another of its vertices), so the blade cannot be triangulated.
    Triangulation(usize),
    /// The veins' convolution skeleton refused a segment or the field (e.g. the sinc
    /// kernel, which convolves points only).
    #[error(transparent)]
    Skeleton(#[from] skelform_skeleton::SkeletonError),
}
