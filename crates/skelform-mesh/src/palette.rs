//! The colours of region pairs, shared by every output that colours a mesh.
//!
//! The glTF writer gives each region pair's material one of these, and the renderer paints
//! each pair's faces with the same one, so a picture and the file it was made from agree (a
//! sheet the picture's legend shows in blue is blue in a viewer of the `.glb` too). Colours
//! are assigned by rank, not by id: the `k`-th distinct label of a mesh, in sorted order,
//! takes [`region_colour`]`(k)`, so the first few pairs of any mesh get the most distinct
//! colours whatever their ids.
//!
//! All colours are sRGB bytes; a writer that needs linear light (glTF's
//! `baseColorFactor`) converts them itself.

/// The palette, in the order colours are handed out: eight well-separated hues, then a
/// brown and a neutral grey, for meshes with up to ten region pairs; an eleventh pair starts
/// over.
pub const REGION_COLOURS: [[u8; 3]; 10] = [
    [84, 140, 204],
    [230, 142, 62],
    [104, 176, 96],
    [206, 86, 86],
    [152, 118, 196],
    [72, 178, 178],
    [214, 182, 72],
    [210, 124, 172],
    [140, 110, 82],
    [150, 150, 150],
];

/// The colour of a surface without region labels: a pale blue-grey that shades well and is
/// none of the palette's colours.
pub const SURFACE_COLOUR: [u8; 3] = [176, 192, 214];

/// The colour of the `index`-th distinct region pair of a mesh (sorted order), cycling
/// through [`REGION_COLOURS`].
pub fn region_colour(index: usize) -> [u8; 3] {
    REGION_COLOURS[index % REGION_COLOURS.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_cycle_and_stay_distinct_from_the_surface() {
        assert_eq!(region_colour(0), REGION_COLOURS[0]);
        assert_eq!(region_colour(REGION_COLOURS.len() + 2), REGION_COLOURS[2]);
        assert!(!REGION_COLOURS.contains(&SURFACE_COLOUR));
    }
}
