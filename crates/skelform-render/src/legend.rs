//! The legend: a box in the top-left corner with a swatch and a label for each region pair
//! and for the curves, drawn in a small built-in bitmap font (so no font files or font
//! crates are needed, and the text is the same bit for bit everywhere).

use crate::image::{Image, Rgb};

/// What a legend line shows before its text.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Swatch {
    /// A filled square: a region pair's colour.
    Fill(Rgb),
    /// A short thick line: the curves' colour.
    Line(Rgb),
    /// Nothing (a heading or a "more" line).
    None,
}

/// 5 × 7 glyphs, one row a byte, bit 4 the leftmost column. Letters are capitals only;
/// lower-case text is drawn in capitals.
fn glyph(c: char) -> [u8; 7] {
    match c.to_ascii_uppercase() {
        '0' => [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E],
        '1' => [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E],
        '2' => [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F],
        '3' => [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E],
        '4' => [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02],
        '5' => [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E],
        '6' => [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E],
        '7' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E],
        '9' => [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C],
        'A' => [0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'B' => [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E],
        'C' => [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E],
        'D' => [0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C],
        'E' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F],
        'F' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10],
        'G' => [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F],
        'H' => [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'I' => [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
        'J' => [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C],
        'K' => [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11],
        'L' => [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F],
        'M' => [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11],
        'N' => [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11],
        'O' => [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'P' => [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10],
        'Q' => [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D],
        'R' => [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11],
        'S' => [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E],
        'T' => [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        'U' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'V' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04],
        'W' => [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A],
        'X' => [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11],
        'Y' => [0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04],
        'Z' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F],
        ' ' => [0; 7],
        '-' => [0, 0, 0, 0x1F, 0, 0, 0],
        '+' => [0, 0x04, 0x04, 0x1F, 0x04, 0x04, 0],
        '|' => [0x04; 7],
        '(' => [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02],
        ')' => [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08],
        ',' => [0, 0, 0, 0, 0x0C, 0x04, 0x08],
        '.' => [0, 0, 0, 0, 0, 0x0C, 0x0C],
        ':' => [0, 0x0C, 0x0C, 0, 0x0C, 0x0C, 0],
        '/' => [0x01, 0x02, 0x02, 0x04, 0x08, 0x08, 0x10],
        '_' => [0, 0, 0, 0, 0, 0, 0x1F],
        _ => [0x0E, 0x11, 0x01, 0x02, 0x04, 0, 0x04],
    }
}

/// Draws `text` with its top-left corner at `(x, y)`, each font pixel `scale` pixels wide.
pub(crate) fn draw_text(img: &mut Image, x: i64, y: i64, text: &str, scale: i64, colour: Rgb) {
    for (k, c) in text.chars().enumerate() {
        let g = glyph(c);
        let x0 = x + k as i64 * 6 * scale;
        for (row, bits) in g.iter().enumerate() {
            for col in 0..5 {
                if bits & (0x10 >> col) != 0 {
                    for dy in 0..scale {
                        for dx in 0..scale {
                            img.set(x0 + col * scale + dx, y + row as i64 * scale + dy, colour);
                        }
                    }
                }
            }
        }
    }
}

/// Draws the legend box in the top-left corner. Lines past what fits in the image's height
/// are summarised as "+N more".
pub(crate) fn draw(img: &mut Image, entries: &[(Swatch, String)]) {
    if entries.is_empty() {
        return;
    }
    let scale = (i64::from(img.width.min(img.height)) / 300).max(1);
    let line = 11 * scale;
    let pad = 5 * scale;
    let fits = ((i64::from(img.height) - 2 * pad - 8 * scale) / line).max(1) as usize;
    let mut shown: Vec<(Swatch, String)> = entries.to_vec();
    if shown.len() > fits {
        let more = shown.len() - (fits - 1).max(1);
        shown.truncate((fits - 1).max(1));
        shown.push((Swatch::None, format!("+{more} more")));
    }
    let text_w = shown.iter().map(|(_, t)| t.chars().count() as i64).max().unwrap_or(0) * 6 * scale;
    let swatch = 8 * scale;
    let (x0, y0) = (pad, pad);
    let w = pad + swatch + 4 * scale + text_w + pad;
    let h = pad + shown.len() as i64 * line - 4 * scale + pad;
    for y in y0..y0 + h {
        for x in x0..x0 + w {
            let border = y == y0 || y == y0 + h - 1 || x == x0 || x == x0 + w - 1;
            if border {
                img.blend(x, y, [120, 120, 120], 0.9);
            } else {
                img.blend(x, y, [255, 255, 255], 0.85);
            }
        }
    }
    for (k, (sw, text)) in shown.iter().enumerate() {
        let top = y0 + pad + k as i64 * line;
        let sx = x0 + pad;
        match *sw {
            Swatch::Fill(c) => {
                for y in top..top + 7 * scale {
                    for x in sx..sx + swatch {
                        let edge =
                            y == top || y == top + 7 * scale - 1 || x == sx || x == sx + swatch - 1;
                        img.set(x, y, if edge { [60, 60, 60] } else { c });
                    }
                }
            }
            Swatch::Line(c) => {
                let mid = top + 3 * scale;
                for y in mid - scale / 2 - 1..mid + scale / 2 + 1 {
                    for x in sx..sx + swatch {
                        img.set(x, y, c);
                    }
                }
            }
            Swatch::None => {}
        }
        draw_text(img, sx + swatch + 4 * scale, top, text, scale, [30, 30, 30]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_draws_the_glyph_pixels() {
        let mut img = Image::new(20, 10, [255; 3]);
        draw_text(&mut img, 1, 1, "1", 1, [0; 3]);
        // The "1" has its stem in column 2 of the glyph, on every row.
        for row in 0..7 {
            assert_eq!(img.pixel(3, row + 1), [0; 3]);
        }
        assert_eq!(img.pixel(1, 1), [255; 3]);
        let dark = img.pixels.iter().filter(|p| **p == [0; 3]).count();
        assert_eq!(dark, 1 + 2 + 4 + 3);
    }

    #[test]
    fn long_legends_are_summarised() {
        let mut img = Image::new(200, 60, [255; 3]);
        let entries: Vec<_> =
            (0..20).map(|i| (Swatch::Fill([i * 10, 0, 0]), format!("{i}-x"))).collect();
        draw(&mut img, &entries);
        // Nothing is drawn below the image; the box stays inside it.
        assert!(img.pixels.iter().any(|p| *p != [255; 3]));
    }
}
