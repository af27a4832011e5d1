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

/// A grayscale PNG of `w × h` pixels at a fresh path in the temporary folder (a folder
/// per `prefix` and process).
pub(crate) fn grayscale_png(
    prefix: &str,
    name: &str,
    w: u32,
    h: u32,
    value: impl Fn(u32, u32) -> u8,
) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("{prefix}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
    let mut e = png::Encoder::new(file, w, h);
    e.set_color(png::ColorType::Grayscale);
    e.set_depth(png::BitDepth::Eight);
    let mut wr = e.write_header().unwrap();
    let data: Vec<u8> =
        (0..h).flat_map(|r| (0..w).map(move |c| (c, r))).map(|(c, r)| value(c, r)).collect();
    wr.write_image_data(&data).unwrap();
    wr.finish().unwrap();
    path
}
