//! Floating-point images (RGB and one-channel) with PNG output and exact PFM round trips.
//!
//! Renders are kept in linear f32 so that tracers can be compared with the metrics of
//! [`crate::metrics`]; PNG is for looking at them, PFM for storing them losslessly
//! (including hit distances, primitive ids of -1 and infinities).

use std::path::Path;

use glam::Vec3;

use crate::SceneError;

/// An RGB f32 image (linear radiance), row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major pixels, row 0 at the top: pixel `(x, y)` is `pixels[y * width + x]`.
    pub pixels: Vec<Vec3>,
}

/// A one-channel f32 image (depth, primitive id, traversal cost...), row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct ScalarImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major values, row 0 at the top: pixel `(x, y)` is `values[y * width + x]`.
    pub values: Vec<f32>,
}

/// An 8-bit sRGB image for display (heat maps, legends, strips), row-major, row 0 at the
/// top; unlike [`Image`] it is written to PNG as it is, without gamma.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Rgb8Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major pixels, three bytes each.
    pub rgb: Vec<u8>,
}

impl Rgb8Image {
    /// A `width` x `height` image filled with `color`.
    pub fn filled(width: u32, height: u32, color: [u8; 3]) -> Rgb8Image {
        let rgb = color.repeat(width as usize * height as usize);
        Rgb8Image { width, height, rgb }
    }

    /// The colour of pixel `(x, y)`. Panics outside the image.
    pub fn get(&self, x: u32, y: u32) -> [u8; 3] {
        let i = 3 * index(self.width, self.height, x, y);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// Sets pixel `(x, y)`; pixels outside the image are ignored (drawing clips).
    pub fn put(&mut self, x: i64, y: i64, color: [u8; 3]) {
        if x >= 0 && y >= 0 && x < i64::from(self.width) && y < i64::from(self.height) {
            let i = 3 * (y as usize * self.width as usize + x as usize);
            self.rgb[i..i + 3].copy_from_slice(&color);
        }
    }

    /// Fills the rectangle `[x, x + w) x [y, y + h)`, clipped to the image.
    pub fn fill_rect(&mut self, x: i64, y: i64, w: u32, h: u32, color: [u8; 3]) {
        for yy in y..y + i64::from(h) {
            for xx in x..x + i64::from(w) {
                self.put(xx, yy, color);
            }
        }
    }

    /// Copies `other` with its top left corner at `(x, y)`, clipped to the image.
    pub fn blit(&mut self, other: &Rgb8Image, x: i64, y: i64) {
        for yy in 0..other.height {
            for xx in 0..other.width {
                self.put(x + i64::from(xx), y + i64::from(yy), other.get(xx, yy));
            }
        }
    }

    /// Writes an 8-bit RGB PNG.
    pub fn save_png(&self, path: &Path) -> Result<(), SceneError> {
        write_png(path, self.width, self.height, &self.rgb)
    }
}

impl Image {
    /// A black `width` x `height` image.
    pub fn new(width: u32, height: u32) -> Image {
        Image { width, height, pixels: vec![Vec3::ZERO; width as usize * height as usize] }
    }

    /// The pixel at column `x`, row `y` (row 0 at the top). Panics if out of range.
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[index(self.width, self.height, x, y)]
    }

    /// Sets the pixel at column `x`, row `y`. Panics if out of range.
    pub fn set(&mut self, x: u32, y: u32, value: Vec3) {
        let i = index(self.width, self.height, x, y);
        self.pixels[i] = value;
    }

    /// Writes an 8-bit sRGB-style PNG: each channel clamped to [0, 1] (NaN as 0, `+inf` as
    /// 1, `-inf` as 0) and encoded with gamma 2.2.
    pub fn save_png(&self, path: &Path) -> Result<(), SceneError> {
        self.to_rgb8().save_png(path)
    }

    /// The 8-bit image [`Image::save_png`] writes: each channel clamped to [0, 1] (NaN as 0)
    /// and encoded with gamma 2.2.
    pub fn to_rgb8(&self) -> Rgb8Image {
        let rgb = self.pixels.iter().flat_map(|p| p.to_array()).map(encode_gamma).collect();
        Rgb8Image { width: self.width, height: self.height, rgb }
    }

    /// Writes a little-endian colour PFM (`PF`, scale -1.0), rows stored bottom to top as the
    /// format requires; [`Image::load_pfm`] reads it back bit for bit.
    pub fn save_pfm(&self, path: &Path) -> Result<(), SceneError> {
        let data: Vec<f32> = self.pixels.iter().flat_map(|p| p.to_array()).collect();
        write_pfm(path, "PF", self.width, self.height, 3, &data)
    }

    /// Reads a colour PFM (`PF`, either byte order). A NaN, infinite or zero scale in the
    /// header is an error naming the file; NaN and infinite samples are kept as they are.
    pub fn load_pfm(path: &Path) -> Result<Image, SceneError> {
        let (width, height, data) = read_pfm(path, 3)?;
        let pixels = data.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
        Ok(Image { width, height, pixels })
    }
}

impl ScalarImage {
    /// A `width` x `height` image of zeros.
    pub fn new(width: u32, height: u32) -> ScalarImage {
        ScalarImage { width, height, values: vec![0.0; width as usize * height as usize] }
    }

    /// The value at column `x`, row `y` (row 0 at the top). Panics if out of range.
    pub fn get(&self, x: u32, y: u32) -> f32 {
        self.values[index(self.width, self.height, x, y)]
    }

    /// Sets the value at column `x`, row `y`. Panics if out of range.
    pub fn set(&mut self, x: u32, y: u32, value: f32) {
        let i = index(self.width, self.height, x, y);
        self.values[i] = value;
    }

    /// The smallest and largest finite values, or `None` if there is none.
    pub fn finite_range(&self) -> Option<(f32, f32)> {
        self.values.iter().copied().filter(|v| v.is_finite()).fold(None, |r, v| match r {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
    }

    /// Writes an 8-bit PNG mapping the finite range `[min, max]` linearly to black..white
    /// (mid grey if all finite values are equal); NaN and infinities are drawn red.
    pub fn save_png(&self, path: &Path) -> Result<(), SceneError> {
        let (lo, hi) = self.finite_range().unwrap_or((0.0, 0.0));
        let bytes: Vec<u8> = self
            .values
            .iter()
            .flat_map(|&v| {
                if !v.is_finite() {
                    [255, 0, 0]
                } else if hi > lo {
                    let g = (f64::from(v - lo) / f64::from(hi - lo) * 255.0).round() as u8;
                    [g; 3]
                } else {
                    [128; 3]
                }
            })
            .collect();
        write_png(path, self.width, self.height, &bytes)
    }

    /// Writes a little-endian greyscale PFM (`Pf`, scale -1.0), rows bottom to top.
    pub fn save_pfm(&self, path: &Path) -> Result<(), SceneError> {
        write_pfm(path, "Pf", self.width, self.height, 1, &self.values)
    }

    /// Reads a greyscale PFM (`Pf`, either byte order), with the checks of
    /// [`Image::load_pfm`].
    pub fn load_pfm(path: &Path) -> Result<ScalarImage, SceneError> {
        let (width, height, values) = read_pfm(path, 1)?;
        Ok(ScalarImage { width, height, values })
    }
}

/// The row-major index of pixel `(x, y)`, panicking with a clear message if out of range.
fn index(width: u32, height: u32, x: u32, y: u32) -> usize {
    assert!(x < width && y < height, "pixel ({x}, {y}) outside a {width}x{height} image");
    y as usize * width as usize + x as usize
}

/// One channel of linear radiance as the PNG byte [`Image::save_png`] writes: clamped to
/// [0, 1] (NaN as 0), gamma 1/2.2, rounded.
pub fn encode_gamma(v: f32) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    (v.powf(1.0 / 2.2) * 255.0).round() as u8
}

fn io_error(path: &Path, source: std::io::Error) -> SceneError {
    SceneError::Io { path: path.to_path_buf(), source }
}

fn parse_error(path: &Path, message: impl Into<String>) -> SceneError {
    SceneError::Parse { path: path.to_path_buf(), message: message.into() }
}

fn write_png(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<(), SceneError> {
    image::save_buffer_with_format(path, rgb, width, height, image::ColorType::Rgb8, image::ImageFormat::Png).map_err(
        |e| match e {
            image::ImageError::IoError(source) => io_error(path, source),
            other => io_error(path, std::io::Error::other(other)),
        },
    )
}

/// Writes a PFM with `channels` floats per pixel; `data` is row-major with row 0 at the top.
fn write_pfm(
    path: &Path,
    magic: &str,
    width: u32,
    height: u32,
    channels: usize,
    data: &[f32],
) -> Result<(), SceneError> {
    let mut bytes = format!("{magic}\n{width} {height}\n-1.0\n").into_bytes();
    let row_len = width as usize * channels;
    bytes.reserve(data.len() * 4);
    if row_len > 0 {
        // PFM stores the bottom row first.
        for row in data.chunks_exact(row_len).rev() {
            bytes.extend(row.iter().flat_map(|v| v.to_le_bytes()));
        }
    }
    std::fs::write(path, bytes).map_err(|e| io_error(path, e))
}

/// Reads a PFM with `channels` floats per pixel, returning width, height and the data
/// row-major with row 0 at the top.
fn read_pfm(path: &Path, channels: usize) -> Result<(u32, u32, Vec<f32>), SceneError> {
    let bytes = std::fs::read(path).map_err(|e| io_error(path, e))?;
    // The header is three whitespace-separated tokens, the last followed by one whitespace byte.
    let mut tokens = Vec::new();
    let mut pos = 0;
    while tokens.len() < 4 {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if start == pos || pos - start > 32 {
            return Err(parse_error(path, "truncated or malformed PFM header"));
        }
        tokens.push(String::from_utf8_lossy(&bytes[start..pos]).into_owned());
    }
    // `tokens` holds magic, width, height, scale; skip the single separator after the scale.
    pos += 1;
    let expected = if channels == 3 { "PF" } else { "Pf" };
    if tokens[0] != expected {
        return Err(parse_error(path, format!("expected a '{expected}' PFM, found '{}'", tokens[0])));
    }
    let dim = |s: &str| s.parse::<u32>().map_err(|_| parse_error(path, format!("bad PFM size '{s}'")));
    let (width, height) = (dim(&tokens[1])?, dim(&tokens[2])?);
    let scale: f32 = tokens[3].parse().map_err(|_| parse_error(path, format!("bad PFM scale '{}'", tokens[3])))?;
    if scale == 0.0 || !scale.is_finite() {
        return Err(parse_error(path, format!("bad PFM scale '{}'", tokens[3])));
    }
    let row_len = width as usize * channels;
    let count = row_len.checked_mul(height as usize).ok_or_else(|| parse_error(path, "PFM too large"))?;
    let payload = bytes.get(pos.min(bytes.len())..).unwrap_or_default();
    if payload.len() != count * 4 {
        return Err(parse_error(
            path,
            format!("PFM {width}x{height} needs {} data bytes, found {}", count * 4, payload.len()),
        ));
    }
    let little_endian = scale < 0.0;
    let mut data = Vec::with_capacity(count);
    if row_len > 0 {
        for row in payload.chunks_exact(row_len * 4).rev() {
            data.extend(row.chunks_exact(4).map(|b| {
                let b = [b[0], b[1], b[2], b[3]];
                if little_endian { f32::from_le_bytes(b) } else { f32::from_be_bytes(b) }
            }));
        }
    }
    Ok((width, height, data))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file `name` in a scratch folder of its own (removed when the folder is dropped).
    fn temp_path(name: &str) -> (crate::ScratchDir, std::path::PathBuf) {
        crate::scratch::scratch_file("scenes-image-tests", name)
    }

    fn bits(v: &[f32]) -> Vec<u32> {
        v.iter().map(|f| f.to_bits()).collect()
    }

    #[test]
    fn rgb_pfm_round_trip_is_bit_exact() {
        let mut img = Image::new(3, 2);
        img.set(0, 0, Vec3::new(-1.0, 0.5, f32::INFINITY));
        img.set(2, 1, Vec3::new(f32::NEG_INFINITY, 1e-30, -0.0));
        img.set(2, 0, Vec3::new(123.25, -7.0, 3.0));
        let (_path_dir, path) = temp_path("rgb.pfm");
        img.save_pfm(&path).unwrap();
        let back = Image::load_pfm(&path).unwrap();
        assert_eq!((back.width, back.height), (3, 2));
        let flat = |i: &Image| i.pixels.iter().flat_map(|p| p.to_array()).collect::<Vec<_>>();
        assert_eq!(bits(&flat(&back)), bits(&flat(&img)));
        // The top row is stored last.
        let bytes = std::fs::read(&path).unwrap();
        let last = f32::from_le_bytes(bytes[bytes.len() - 4..].try_into().unwrap());
        assert_eq!(last, 3.0);
    }

    #[test]
    fn scalar_pfm_round_trip_keeps_ids_nan_and_infinities() {
        let mut img = ScalarImage::new(2, 3);
        img.set(0, 0, -1.0);
        img.set(1, 0, f32::INFINITY);
        img.set(0, 2, f32::NAN);
        img.set(1, 2, 16_777_215.0);
        let (_path_dir, path) = temp_path("scalar.pfm");
        img.save_pfm(&path).unwrap();
        let back = ScalarImage::load_pfm(&path).unwrap();
        assert_eq!(bits(&back.values), bits(&img.values));
        // A scalar file is not a colour file.
        assert!(matches!(Image::load_pfm(&path), Err(SceneError::Parse { .. })));
    }

    #[test]
    fn bad_pfm_files_are_errors_naming_the_file() {
        let (_path_dir, path) = temp_path("bad.pfm");
        std::fs::write(&path, b"PF\n2 2\n-1.0\n0000").unwrap();
        let err = Image::load_pfm(&path).unwrap_err().to_string();
        assert!(err.contains("bad.pfm") && err.contains("data bytes"), "{err}");
        std::fs::write(&path, b"PF\n").unwrap();
        assert!(Image::load_pfm(&path).is_err());
        std::fs::write(&path, b"Pf\n99999999 99999999\n-1.0\n").unwrap();
        assert!(ScalarImage::load_pfm(&path).is_err());
        for scale in ["nan", "inf", "-inf", "0"] {
            std::fs::write(
                &path,
                format!("PF\n1 1\n{scale}\n").into_bytes().into_iter().chain([0; 12]).collect::<Vec<u8>>(),
            )
            .unwrap();
            let err = Image::load_pfm(&path).unwrap_err().to_string();
            assert!(err.contains("bad.pfm") && err.contains("bad PFM scale"), "{scale}: {err}");
        }
        let (_missing_dir, missing) = temp_path("missing.pfm");
        assert!(matches!(Image::load_pfm(&missing), Err(SceneError::Io { .. })));
    }

    #[test]
    fn png_files_are_written() {
        let mut img = Image::new(4, 3);
        img.set(1, 1, Vec3::new(2.0, 0.5, f32::NAN));
        img.set(2, 1, Vec3::new(f32::INFINITY, f32::NEG_INFINITY, 0.0));
        let (_path_dir, path) = temp_path("rgb.png");
        img.save_png(&path).unwrap();
        let png = image::open(&path).unwrap().to_rgb8();
        assert_eq!(png.dimensions(), (4, 3));
        assert_eq!(png.get_pixel(1, 1).0, [255, encode_gamma(0.5), 0]);
        assert_eq!(png.get_pixel(2, 1).0, [255, 0, 0]);
        assert_eq!(encode_gamma(0.5), 186);

        let mut s = ScalarImage::new(3, 1);
        s.values = vec![1.0, 3.0, f32::NAN];
        let (_path_dir, path) = temp_path("scalar.png");
        s.save_png(&path).unwrap();
        let png = image::open(&path).unwrap().to_rgb8();
        assert_eq!(png.get_pixel(0, 0).0, [0, 0, 0]);
        assert_eq!(png.get_pixel(1, 0).0, [255, 255, 255]);
        assert_eq!(png.get_pixel(2, 0).0, [255, 0, 0]);
    }

    #[test]
    fn unwritable_png_path_is_an_io_error() {
        let img = Image::new(1, 1);
        let err = img.save_png(Path::new("/nonexistent-dir/x.png")).unwrap_err();
        assert!(matches!(err, SceneError::Io { .. }));
    }
}
