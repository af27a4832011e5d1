//! What the unit tests of the scene sections share.

use crate::{Scene, SceneError};

/// The position and message of the error a scene text was refused with (`text` is shown if it
/// was accepted). Tests of a section check that a mistake is reported where it is.
pub(crate) fn error_position(
    result: Result<Scene, SceneError>,
    text: &str,
) -> (usize, usize, String) {
    match result {
        Err(SceneError::At { line, column, message, .. }) => (line, column, message),
        Err(e) => panic!("an error without a position: {e}"),
        Ok(_) => panic!("accepted:\n{text}"),
    }
}
