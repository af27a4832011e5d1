//! The picture: 8-bit sRGB pixels, PNG encoding (the `png` crate), atomic files, and
//! animated PNG for turntables.

use std::io;
use std::path::Path;

use crate::RenderError;

/// An sRGB colour, 8 bits a channel.
pub type Rgb = [u8; 3];

/// A picture: `width × height` sRGB pixels, row by row from the top.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// Pixels per row; a rendered picture has 1 to [`MAX_SIDE`](crate::MAX_SIDE).
    pub width: u32,
    /// Rows of pixels; `pixels` holds `width * height` of them.
    pub height: u32,
    /// `width * height` pixels, top row first.
    pub pixels: Vec<Rgb>,
}

impl Image {
    /// A picture of one colour.
    pub fn new(width: u32, height: u32, fill: Rgb) -> Image {
        Image { width, height, pixels: vec![fill; width as usize * height as usize] }
    }

    /// The pixel in column `x`, row `y` (from the top).
    ///
    /// # Panics
    /// If `(x, y)` is outside the image.
    pub fn pixel(&self, x: u32, y: u32) -> Rgb {
        assert!(x < self.width && y < self.height, "pixel ({x}, {y}) outside the image");
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    pub(crate) fn set(&mut self, x: i64, y: i64, c: Rgb) {
        if x >= 0 && y >= 0 && x < i64::from(self.width) && y < i64::from(self.height) {
            self.pixels[y as usize * self.width as usize + x as usize] = c;
        }
    }

    /// Blends `c` over the pixel with opacity `a` (in sRGB values; used for overlays).
    pub(crate) fn blend(&mut self, x: i64, y: i64, c: Rgb, a: f32) {
        if x >= 0 && y >= 0 && x < i64::from(self.width) && y < i64::from(self.height) {
            let p = &mut self.pixels[y as usize * self.width as usize + x as usize];
            for k in 0..3 {
                p[k] = (f32::from(p[k]) * (1.0 - a) + f32::from(c[k]) * a).round() as u8;
            }
        }
    }

    /// The raw RGB bytes, row by row.
    pub fn as_bytes(&self) -> Vec<u8> {
        self.pixels.iter().flatten().copied().collect()
    }

    /// The picture as a PNG file's bytes (8-bit RGB, marked sRGB).
    pub fn encode_png(&self) -> Result<Vec<u8>, RenderError> {
        encode(std::slice::from_ref(self), 0)
    }

    /// Writes the picture as PNG to `path`, atomically: a temporary file in the same folder,
    /// renamed over `path` once complete, so a failure never leaves a partial picture.
    pub fn write_png(&self, path: &Path) -> Result<(), RenderError> {
        write_atomic(path, &self.encode_png()?)
    }
}

/// Writes `frames` as one animated PNG (APNG), looping forever, each frame shown for
/// `delay_ms` milliseconds; viewers without APNG support show the first frame. Atomic like
/// [`Image::write_png`]. All frames must have the same size.
pub fn write_apng(path: &Path, frames: &[Image], delay_ms: u16) -> Result<(), RenderError> {
    write_atomic(path, &encode(frames, delay_ms)?)
}

/// Writes an animated PNG of `count` frames drawn one at a time by `frame(k)`, atomically:
/// only one frame is ever held, whatever the count and size.
pub(crate) fn write_apng_streamed(
    path: &Path,
    (width, height): (u32, u32),
    count: u32,
    delay_ms: u16,
    mut frame: impl FnMut(u32) -> Result<Image, RenderError>,
) -> Result<(), RenderError> {
    skelform_mesh::io::atomic::write_with(path, |file| {
        let mut out = io::BufWriter::new(file);
        let mut frames = (0..count).map(|k| frame(k).map(std::borrow::Cow::Owned));
        encode_frames(&mut out, width, height, count, delay_ms, &mut frames)?;
        io::Write::flush(&mut out)
            .map_err(|e| RenderError::Write { path: path.to_path_buf(), source: e })
    })
    .map_err(|e| match e {
        skelform_mesh::io::atomic::AtomicError::Io(source) => {
            RenderError::Write { path: path.to_path_buf(), source }
        }
        skelform_mesh::io::atomic::AtomicError::Write(e) => e,
    })
}

/// Encodes one image (`frames.len() == 1`) or an animation.
pub fn encode(frames: &[Image], delay_ms: u16) -> Result<Vec<u8>, RenderError> {
    let first = frames.first().ok_or_else(|| RenderError::Settings("no frames".into()))?;
    let n =
        u32::try_from(frames.len()).map_err(|_| RenderError::Settings("too many frames".into()))?;
    let mut out = Vec::new();
    let mut frames = frames.iter().map(|f| Ok(std::borrow::Cow::Borrowed(f)));
    encode_frames(&mut out, first.width, first.height, n, delay_ms, &mut frames)?;
    Ok(out)
}

/// Encodes `count` frames of `width × height` as they come from `frames` (one still picture
/// when `count` is 1), so that an animation of any length holds one frame at a time.
pub(crate) fn encode_frames<'a, W: io::Write>(
    out: W,
    width: u32,
    height: u32,
    count: u32,
    delay_ms: u16,
    frames: &mut dyn Iterator<Item = Result<std::borrow::Cow<'a, Image>, RenderError>>,
) -> Result<(), RenderError> {
    let mut enc = png::Encoder::new(out, width, height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    // Rendered pictures have large flat areas; the adaptive filter with the default
    // deflate level keeps the gallery small without slowing big renders much.
    enc.set_compression(png::Compression::Balanced);
    if count > 1 {
        enc.set_animated(count, 0).map_err(RenderError::Encode)?;
        enc.set_frame_delay(delay_ms, 1000).map_err(RenderError::Encode)?;
    }
    let mut w = enc.write_header().map_err(RenderError::Encode)?;
    let mut written = 0;
    for f in frames.take(count as usize) {
        let f = f?;
        if f.width != width || f.height != height {
            return Err(RenderError::Settings("the frames differ in size".into()));
        }
        w.write_image_data(&f.as_bytes()).map_err(RenderError::Encode)?;
        written += 1;
    }
    if written != count {
        return Err(RenderError::Settings(format!("{written} frames given for {count}")));
    }
    w.finish().map_err(RenderError::Encode)
}

/// Writes `bytes` to `path` atomically ([`skelform_mesh::io::atomic`]): a temporary file
/// beside `path`, synced and renamed over it; on any error `path` is untouched.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), RenderError> {
    skelform_mesh::io::atomic::write(path, bytes)
        .map_err(|source| RenderError::Write { path: path.to_path_buf(), source })
}

/// Linear light to an sRGB byte.
pub(crate) fn to_srgb(c: f32) -> u8 {
    let c = c.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0 + 0.5) as u8
}

/// An sRGB byte to linear light.
pub(crate) fn to_linear(c: u8) -> f32 {
    to_linear_unit(f32::from(c) / 255.0)
}

/// An sRGB component in `[0, 1]` (clamped) as linear light.
pub(crate) fn to_linear_unit(s: f32) -> f32 {
    let s = s.clamp(0.0, 1.0);
    if s <= 0.040_45 { s / 12.92 } else { ((s + 0.055) / 1.055).powf(2.4) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips() {
        for c in 0..=255u8 {
            assert_eq!(to_srgb(to_linear(c)), c);
        }
    }

    #[test]
    fn png_decodes_to_the_same_pixels() {
        let mut img = Image::new(3, 2, [10, 20, 30]);
        img.set(2, 1, [200, 100, 0]);
        let bytes = img.encode_png().unwrap();
        let dec = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = dec.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (3, 2));
        assert_eq!(&buf[..info.buffer_size()], &img.as_bytes()[..]);
    }
}
