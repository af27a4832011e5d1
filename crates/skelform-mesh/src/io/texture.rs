//! A [`Texture`] as PNG: what the glb writer embeds and the glb reader takes back.
//!
//! Written: 8-bit RGBA, marked sRGB, rows from the top (the texture's own order), so the
//! bytes are the same for the same texture on every run. Read: any PNG the `png` crate
//! decodes (palette, grey, 16-bit, with or without alpha), expanded to 8-bit RGBA; the
//! header's size is checked against [`Texture::MAX_SIDE`] before the pixels are allocated.

use super::IoError;
use crate::mesh::Texture;

/// The PNG file of `t`.
pub fn encode_png(t: &Texture) -> Result<Vec<u8>, IoError> {
    t.validate().map_err(IoError::invalid)?;
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, t.width, t.height);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    enc.set_compression(png::Compression::Balanced);
    let fail = |e: png::EncodingError| IoError::unsupported(format!("cannot encode the PNG: {e}"));
    let mut w = enc.write_header().map_err(fail)?;
    w.write_image_data(&t.rgba).map_err(fail)?;
    w.finish().map_err(fail)?;
    Ok(out)
}

/// The texture in a PNG file, or why it cannot be read (the message names no offset: the
/// caller knows where the PNG lies).
pub fn decode_png(bytes: &[u8]) -> Result<Texture, String> {
    let mut dec = png::Decoder::new(std::io::Cursor::new(bytes));
    dec.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = dec.read_info().map_err(|e| format!("not a readable PNG: {e}"))?;
    let (width, height) = (reader.info().width, reader.info().height);
    if !(1..=Texture::MAX_SIDE).contains(&width) || !(1..=Texture::MAX_SIDE).contains(&height) {
        return Err(format!(
            "a PNG of {width} x {height} pixels; textures are 1 to {} a side",
            Texture::MAX_SIDE
        ));
    }
    let size = reader.output_buffer_size().ok_or("the PNG is too large to decode")?;
    let mut buf = vec![0; size];
    let info = reader.next_frame(&mut buf).map_err(|e| format!("a damaged PNG: {e}"))?;
    let data = &buf[..info.buffer_size()];
    let n = width as usize * height as usize;
    let rgba: Vec<u8> = match info.color_type {
        png::ColorType::Rgba if data.len() == 4 * n => data.to_vec(),
        png::ColorType::Rgb if data.len() == 3 * n => {
            data.chunks_exact(3).flat_map(|c| [c[0], c[1], c[2], 255]).collect()
        }
        png::ColorType::GrayscaleAlpha if data.len() == 2 * n => {
            data.chunks_exact(2).flat_map(|c| [c[0], c[0], c[0], c[1]]).collect()
        }
        png::ColorType::Grayscale if data.len() == n => {
            data.iter().flat_map(|&g| [g, g, g, 255]).collect()
        }
        other => return Err(format!("an unexpected PNG layout ({other:?}, {} bytes)", data.len())),
    };
    Ok(Texture { width, height, rgba })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_round_trips_and_refuses_damage() {
        let rgba: Vec<u8> = (0..3 * 2 * 4).map(|k| (k * 11) as u8).collect();
        let t = Texture { width: 3, height: 2, rgba };
        let bytes = encode_png(&t).unwrap();
        assert_eq!(encode_png(&t).unwrap(), bytes);
        assert_eq!(decode_png(&bytes).unwrap(), t);
        assert!(decode_png(&bytes[..bytes.len() / 2]).is_err());
        assert!(decode_png(b"not a png").is_err());
        assert!(encode_png(&Texture { width: 2, height: 2, rgba: vec![0; 3] }).is_err());
    }
}
