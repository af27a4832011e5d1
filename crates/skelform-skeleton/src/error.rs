//! What can be wrong with a skeleton.

/// A skeleton, element or setting that cannot be used, and why. Messages name the value so
/// that a scene loader can add the file position and pass them on unchanged.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SkeletonError {
    #[error("coordinates must be finite numbers")]
    NonFinite,
    #[error("radius must be a positive length (got {0})")]
    BadRadius(f64),
    #[error("strength must be a finite number (got {0})")]
    BadStrength(f64),
    #[error("segment has zero length: both ends are at {0:?} (use a point for a point source)")]
    ZeroLengthSegment([f64; 3]),
    #[error("a polyline needs at least 2 points (got {0})")]
    ShortPolyline(usize),
    #[error("polyline point {index} repeats the point before it ({point:?}): zero-length segment")]
    RepeatedPolylinePoint { index: usize, point: [f64; 3] },
    #[error("a polygon needs at least 3 vertices (got {0})")]
    TooFewVertices(usize),
    #[error("polygon edge {0} has zero length (vertex {0} repeats the next one)")]
    ZeroLengthEdge(usize),
    #[error("polygon is degenerate: its vertices are (nearly) collinear, area {area:.3e}")]
    DegeneratePolygon { area: f64 },
    #[error("polygon is not planar: vertex {vertex} is {distance:.3e} off the polygon's plane")]
    NotPlanar { vertex: usize, distance: f64 },
    #[error("polygon edges {0} and {1} cross: a polygon must be simple")]
    SelfIntersecting(usize, usize),
    #[error("unknown group '{0}'")]
    UnknownGroup(String),
    #[error("group '{0}' is defined twice")]
    DuplicateGroup(String),
    #[error("{name} must be {expected} (got {value})")]
    BadParameter { name: &'static str, value: f64, expected: &'static str },
    #[error("unknown joint '{0}'")]
    UnknownJoint(String),
    #[error("joint '{0}' is defined twice")]
    DuplicateJoint(String),
    #[error("radius must be one number or one per point: {points} points, {radii} radii")]
    RadiusCount { points: usize, radii: usize },
    #[error("only segments (and polylines and curves) can taper: give one radius")]
    TaperNeedsSegment,
    #[error(
        "junction at {at:?} needs at least 2 limbs (segments with an end there), found {found}"
    )]
    TooFewLimbs { at: [f64; 3], found: usize },
    #[error("the limbs of the junction at {0:?} are in different blend groups")]
    LimbsInSeveralGroups([f64; 3]),
    #[error("direction must be a non-zero vector (got {0:?})")]
    BadDirection([f64; 3]),
    #[error("junctions apply to the convolution blend only, not to {0}")]
    JunctionNeedsConvolution(&'static str),
    #[error("image_resolution must be between 4 and {max} pixels (got {0})", max = crate::image::MAX_IMAGE_RESOLUTION)]
    BadImageResolution(usize),
    #[error("joint '{joint}' turns about {axes} axes, so it takes {axes} angles (got {got})")]
    AngleCount { joint: String, axes: usize, got: usize },
    #[error("there is no element {0}")]
    UnknownElement(usize),
    #[error("the skeleton has no elements")]
    Empty,
    #[error(
        "the {kernel} kernel convolves points only: it is not separable, so a {shape}'s \
         convolution with it has no closed form; use blend = \"sum\" (the {kernel} of the \
         distance to each element) or another kernel"
    )]
    /// `element`: the index of the first segment or polygon.
    KernelConvolvesPointsOnly { kernel: &'static str, shape: &'static str, element: usize },
    #[error("iso applies to density blends (convolution, sum, combination), not to {0}")]
    IsoNotApplicable(&'static str),
}
