//! What can be wrong with a skeleton.

/// A skeleton, element or setting that cannot be used, and why. Messages name the value so
/// that a scene loader can add the file position and pass them on unchanged.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SkeletonError {
    /// A coordinate, direction, offset, rotation or joint angle was NaN or infinite; nothing
    /// of the skeleton is built from it, since one NaN would spread to every field value.
    #[error("coordinates must be finite numbers")]
    NonFinite,
    #[error("radius must be a positive length (got {0})")]
    /// An element radius (or a tapered segment's end radius) that is not a finite positive
    /// length; the radius is where a lone element's surface lies, in scene units.
    BadRadius(f64),
    #[error("strength must be a finite number (got {0})")]
    /// A strength (the weight on an element's density) that is NaN or infinite; any finite
    /// value is accepted, negative ones carve.
    BadStrength(f64),
    #[error("colour components must be numbers from 0 to 1 (got {0:?})")]
    /// A colour (red, green, blue) with a component outside `[0, 1]` or not a number.
    BadColor([f64; 3]),
    #[error("limb {0} does not exist (a child's parent must be added before it)")]
    /// A ramiform child names a parent limb that is not (yet) there.
    UnknownLimb(usize),
    #[error("a ramiform may have at most {max} limbs (got {0})", max = crate::ramiform::MAX_LIMBS)]
    /// A ramiform with more than [`MAX_LIMBS`](crate::ramiform::MAX_LIMBS) limbs; refused
    /// when the limb over the limit is added, before any radius is matched.
    TooManyLimbs(usize),
    #[error("limb {limb} would be {depth} limbs deep, over the limit of {max} (a root is depth 1)", max = crate::ramiform::MAX_DEPTH)]
    /// A ramiform child deeper than [`MAX_DEPTH`](crate::ramiform::MAX_DEPTH) limbs below
    /// its root: evaluation recurses once per level.
    TooDeep {
        /// The index the limb would have had.
        limb: usize,
        /// Its depth (a root is 1).
        depth: usize,
    },
    #[error(
        "matching the ramiform's radii would take {work} limb searches (the searches along directions at each parent times the limbs below it, summed), over the limit of {max}: use fewer directions or a smaller tree",
        max = crate::ramiform::MAX_JOINT_WORK
    )]
    /// Radius matching whose cost ([`Ramiform::joint_work`](crate::Ramiform::joint_work)) is
    /// over
    /// [`MAX_JOINT_WORK`](crate::ramiform::MAX_JOINT_WORK); refused before any is matched.
    JointWorkTooLarge {
        /// The cost as defined above.
        work: u64,
    },
    #[error("{0}")]
    /// A sweep's section image that cannot be used (its size, or no pixel inside).
    BadSectionImage(String),
    #[error("limb {0} has no children, so it needs a radius")]
    /// A ramiform leaf without a radius: only limbs with children take theirs from them.
    LeafNeedsRadius(usize),
    #[error(
        "limb {0} has children, so its radius is matched to theirs at its end (DIS eq. 5.36); give radii to the leaves only"
    )]
    /// A ramiform limb with children was given a radius.
    ParentRadiusGiven(usize),
    #[error("segment has zero length: both ends are at {0:?} (use a point for a point source)")]
    /// A segment whose ends coincide to 10⁻¹² of their magnitude; the value is the end.
    ZeroLengthSegment([f64; 3]),
    #[error("a polyline needs at least 2 points (got {0})")]
    /// A polyline with fewer than two points; the value is the count given.
    ShortPolyline(usize),
    #[error("polyline point {index} repeats the point before it ({point:?}): zero-length segment")]
    /// Two consecutive polyline points coincide, which would make a zero-length segment.
    RepeatedPolylinePoint {
        /// Index in the polyline of the second of the two equal points.
        index: usize,
        /// Where the repeated point lies.
        point: [f64; 3],
    },
    #[error("a polygon needs at least 3 vertices (got {0})")]
    /// A polygon with fewer than three vertices; the value is the count given.
    TooFewVertices(usize),
    #[error("polygon edge {0} has zero length (vertex {0} repeats the next one)")]
    /// Polygon vertex `i` coincides with vertex `i + 1` (cyclically) to 10⁻¹² of the
    /// polygon's size; the value is `i`, the edge's index.
    ZeroLengthEdge(usize),
    #[error("polygon is degenerate: its vertices are (nearly) collinear, area {area:.3e}")]
    /// A polygon whose area is (nearly) zero, so that it has no plane and no normal.
    DegeneratePolygon {
        /// The polygon's area (Newell's, in squared scene units); at most 10⁻¹² of its
        /// size squared, or NaN.
        area: f64,
    },
    #[error("polygon is not planar: vertex {vertex} is {distance:.3e} off the polygon's plane")]
    /// A polygon vertex lies off the polygon's plane by more than 10⁻⁶ of the polygon's
    /// size: the convolution integrals assume a planar polygon.
    NotPlanar {
        /// Index of the first vertex found too far from the plane.
        vertex: usize,
        /// Its distance from the plane through the vertices' centroid along Newell's
        /// normal, in scene units.
        distance: f64,
    },
    #[error("polygon edges {0} and {1} cross: a polygon must be simple")]
    /// Two non-adjacent polygon edges touch or cross, so the polygon is not simple; the
    /// values are the indices of the two edges (edge `i` runs from vertex `i` to `i + 1`).
    SelfIntersecting(usize, usize),
    #[error("unknown group '{0}'")]
    /// A group name (or, from the API, `#index`) that the skeleton does not have.
    UnknownGroup(String),
    #[error("group '{0}' is defined twice")]
    /// [`Skeleton::add_group`](crate::Skeleton::add_group) with a name already in use.
    DuplicateGroup(String),
    #[error("{name} must be {expected} (got {value})")]
    /// A numeric setting out of its range: a blend's `range` or `thumbweight`, an iso
    /// value, a curve's splitting tolerance.
    BadParameter {
        /// The setting's name (`range`, `thumbweight`, `iso`, `tolerance`), as the message
        /// shows it.
        name: &'static str,
        /// The value given.
        value: f64,
        /// The accepted range, in words ("a positive number").
        expected: &'static str,
    },
    #[error("unknown joint '{0}'")]
    /// A joint name (or, from the API, `#index`) that the articulated skeleton does not have.
    UnknownJoint(String),
    #[error("joint '{0}' is defined twice")]
    /// [`Articulated::add_joint`](crate::Articulated::add_joint) with a name already in use.
    DuplicateJoint(String),
    #[error("radius must be one number or one per point: {points} points, {radii} radii")]
    /// A tapered polyline whose list of radii is neither one radius nor one per point.
    RadiusCount {
        /// Points of the polyline.
        points: usize,
        /// Radii given.
        radii: usize,
    },
    #[error("only segments (and polylines and curves) can taper: give one radius")]
    /// Different radii or strengths at the two ends of a point or polygon: only segments
    /// interpolate them along their length.
    TaperNeedsSegment,
    #[error(
        "junction at {at:?} needs at least 2 limbs (segments with an end there), found {found}"
    )]
    /// [`Skeleton::add_junction`](crate::Skeleton::add_junction) at a point where fewer than
    /// two segments end (segments passing through it are split there first).
    TooFewLimbs {
        /// The joint as declared.
        at: [f64; 3],
        /// Segments found with an end within 10⁻⁹ (relative) of it.
        found: usize,
    },
    #[error("the limbs of the junction at {0:?} are in different blend groups")]
    /// The limbs meeting at a junction belong to different blend groups, while a junction
    /// blends all of them into one density; the value is the joint.
    LimbsInSeveralGroups([f64; 3]),
    #[error("direction must be a non-zero vector (got {0:?})")]
    /// A junction's direction of convexity that is zero or not finite, so it cannot be
    /// normalised.
    BadDirection([f64; 3]),
    #[error("junctions apply to the convolution blend only, not to {0}")]
    /// A skeleton with junctions built into a field with another blend than convolution:
    /// the joint combination surface (DIS eq. 5.37) combines convolution densities. The
    /// value is the blend's scene-file name.
    JunctionNeedsConvolution(&'static str),
    #[error("image_resolution must be between 4 and {max} pixels (got {0})", max = crate::image::MAX_IMAGE_RESOLUTION)]
    /// [`PolygonMethod::Image`](crate::PolygonMethod::Image) with a resolution outside
    /// 4 ..= [`MAX_IMAGE_RESOLUTION`](crate::MAX_IMAGE_RESOLUTION) pixels.
    BadImageResolution(usize),
    #[error(
        "the {polygons} image-method polygons would take about {work:.1e} pixel operations and {mib} MiB to build, over the limit of {max_work:.0e} operations and {max_mib} MiB: lower image_resolution or use polygon_method = \"exact\"",
        work = *work as f64,
        mib = bytes >> 20,
        max_work = crate::image::MAX_IMAGE_WORK as f64,
        max_mib = crate::image::MAX_IMAGE_BYTES >> 20
    )]
    /// Image-method polygons whose convolution images would together cost more than
    /// [`MAX_IMAGE_WORK`](crate::MAX_IMAGE_WORK) pixel operations or
    /// [`MAX_IMAGE_BYTES`](crate::MAX_IMAGE_BYTES) to build; refused before any is built.
    ImageWorkTooLarge {
        /// Polygons with the image method.
        polygons: usize,
        /// Estimated pixel operations for all of them.
        work: u64,
        /// Bytes held while building them.
        bytes: u64,
    },
    #[error("joint '{joint}' turns about {axes} axes, so it takes {axes} angles (got {got})")]
    /// A joint given another number of angles than it has rotation axes.
    AngleCount {
        /// The joint's name.
        joint: String,
        /// Rotation axes the joint turns about.
        axes: usize,
        /// Angles given.
        got: usize,
    },
    #[error("there is no element {0}")]
    /// An element index at or past the skeleton's length.
    UnknownElement(usize),
    /// A field built from a skeleton with no elements: it would have no surface and no
    /// bounds to polygonize in.
    #[error("the skeleton has no elements")]
    Empty,
    #[error(
        "the {kernel} kernel convolves points only: it is not separable, so a {shape}'s \
         convolution with it has no closed form; use blend = \"sum\" (the {kernel} of the \
         distance to each element) or another kernel"
    )]
    /// A convolution blend with a kernel that has no closed-form convolution for segments
    /// and polygons (the sinc), on a skeleton with a segment or polygon.
    KernelConvolvesPointsOnly {
        /// The kernel's scene-file name.
        kernel: &'static str,
        /// `"segment"` or `"polygon"`.
        shape: &'static str,
        /// The index of the first segment or polygon.
        element: usize,
    },
    #[error("iso applies to density blends (convolution, sum, combination), not to {0}")]
    /// An iso value given to a distance blend (union, super-elliptic), whose surface is
    /// where its value is 0; the value is the blend's scene-file name.
    IsoNotApplicable(&'static str),
    #[error(
        "{weights} per-vertex weights for a polygon of {vertices} vertices: give one per vertex"
    )]
    /// Per-vertex weights (DIS §6.4) whose count is not the polygon's vertex count.
    WeightCount {
        /// How many weights were given.
        weights: usize,
        /// How many vertices the polygon has.
        vertices: usize,
    },
    #[error(
        "per-vertex weights need a polygon that is star-shaped about the average of its vertices: \
         the triangle from that point to edge {edge} folds back or has no area (split the polygon)"
    )]
    /// Per-vertex weights on a polygon that the fan from its vertex average does not cover,
    /// so the weights could not be interpolated over it (see [`crate::weights`]).
    WeightsNotStarShaped {
        /// The first edge whose fan triangle turns the wrong way (0 runs from vertex 0 to 1).
        edge: usize,
    },
    #[error("weight image: {0}")]
    /// A weight image that cannot be used (its size, or a value that is not finite).
    BadWeightImage(String),
    #[error(
        "only polygons take per-vertex weights or a weight image (segments take end strengths)"
    )]
    /// Per-vertex weights or a weight image on a point or segment.
    WeightsNeedPolygon,
    #[error(
        "a polygon with a weight image is convolved by the image method; it cannot use polygon_method = \"exact\""
    )]
    /// The exact polygon method asked of a polygon with a weight image: the dissertation
    /// scales the polygon's raster image by the weight image, so only the image method
    /// applies it.
    WeightImageNeedsImageMethod,
    #[error("per-vertex weights and weight images apply to the convolution blend only, not to {0}")]
    /// A skeleton with weighted polygons built into a field with a blend other than
    /// convolution; the value is the blend's scene-file name.
    WeightsNeedConvolution(&'static str),
}
