//! One error for everything a front end asks of the library, sorted by whose mistake it is.

use skelform_scene::SceneError;

/// Why a scene could not be loaded or meshed.
///
/// [`Error::is_input`] tells a front end whether to blame the input (exit code 2 in the
/// command line, a message beside the edited field in the studio) or the run (exit code 1).
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The scene file cannot be read, or something in it is wrong (with file, line and
    /// column where there is one).
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// An override or a combination of settings that cannot work, e.g. `resolution = 1`, or
    /// the non-manifold method on a scene without regions.
    #[error("{origin}: {message}")]
    Invalid {
        /// The scene the request was about.
        origin: String,
        /// What is wrong and what would be accepted.
        message: String,
    },
    /// The polygonizer refused or stopped: a lattice too large or over the memory limit, a
    /// seed outside the domain, no surface found by the search, or cancellation.
    #[error("{origin}: {source}")]
    Polygonize {
        /// The scene being meshed.
        origin: String,
        /// The polygonizer's own error.
        #[source]
        source: skelform_polygonize::Error,
    },
}

impl Error {
    /// True when the input (scene, overrides) is at fault rather than the run: a bad file, a
    /// bad value, a lattice over the limits, a seed outside the domain. A lattice refused up
    /// front for memory ([`TooMuchMemory`](skelform_polygonize::Error::TooMuchMemory)) is
    /// input; a run that reached the memory limit as it went
    /// ([`MemoryLimit`](skelform_polygonize::Error::MemoryLimit): what it holds grows with
    /// the surface, known only by running) is the run's failure.
    pub fn is_input(&self) -> bool {
        use skelform_polygonize::Error as P;
        match self {
            Error::Scene(SceneError::Io { .. }) => true,
            Error::Scene(_) | Error::Invalid { .. } => true,
            Error::Polygonize { source, .. } => matches!(
                source,
                P::TooMuchMemory { .. } | P::Grid(_) | P::BadSeed { .. } | P::BadOption(_)
            ),
        }
    }

    /// True when the run was cancelled through its [`Control`](crate::Control).
    pub fn is_cancelled(&self) -> bool {
        matches!(self, Error::Polygonize { source: skelform_polygonize::Error::Cancelled, .. })
    }
}
