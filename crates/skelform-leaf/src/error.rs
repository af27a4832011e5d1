//! What can be wrong with a leaf.

/// A leaf that cannot be built, and why. Messages name the value, so that a scene loader can
/// add the file position and pass them on unchanged.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LeafError {
    #[error("{name} must be {expected} (got {value})")]
    BadParameter { name: &'static str, value: f64, expected: &'static str },
    #[error("the blade outline needs at least 3 points (got {0})")]
    TooFewPoints(usize),
    #[error("the blade outline has zero area or crosses itself")]
    BadOutline,
    #[error("vein {vein} {why}")]
    BadVein { vein: usize, why: String },
    #[error("the venation's polygonal web does not tile the blade: {0}")]
    BadWeb(String),
    #[error("cannot triangulate web polygon {0}: no ear is free of other vertices")]
    Triangulation(usize),
    #[error(transparent)]
    Skeleton(#[from] skelform_skeleton::SkeletonError),
}
