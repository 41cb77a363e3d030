//! Pictures for the archives: a canvas that paints shapes given by their signed distance, in
//! the coordinates of an extent, and a minimal PNG encoder (8-bit RGBA, one `IDAT`, no row filter).

use std::io::Write;

use flate2::write::ZlibEncoder;
use flate2::Compression;

/// A rectangle of the terminalsAndIcons coordinate system, (x1, y1) its lower left corner.
#[derive(Clone, Copy)]
pub(super) struct Extent {
    pub x1: f64,
    pub y1: f64,
    pub x2: f64,
    pub y2: f64,
}

/// A colour, 0–255 per channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Rgb(pub u8, pub u8, pub u8);

/// A shape: its signed distance at a point, in coordinate units, negative inside.
pub(super) type Shape = Box<dyn Fn(f64, f64) -> f64>;

/// The rectangle from (x1, y1) to (x2, y2), its corners rounded with `radius`.
pub(super) fn rect(x1: f64, y1: f64, x2: f64, y2: f64, radius: f64) -> Shape {
    let (cx, cy, hx, hy) = ((x1 + x2) / 2.0, (y1 + y2) / 2.0, (x2 - x1) / 2.0, (y2 - y1) / 2.0);
    Box::new(move |x, y| {
        let qx = (x - cx).abs() - hx + radius;
        let qy = (y - cy).abs() - hy + radius;
        qx.max(0.0).hypot(qy.max(0.0)) + qx.max(qy).min(0.0) - radius
    })
}

pub(super) fn circle(cx: f64, cy: f64, radius: f64) -> Shape {
    Box::new(move |x, y| (x - cx).hypot(y - cy) - radius)
}

/// A stroke `half_width` either side of the segment from `a` to `b`, with round ends.
pub(super) fn segment(a: (f64, f64), b: (f64, f64), half_width: f64) -> Shape {
    Box::new(move |x, y| distance_to_segment((x, y), a, b) - half_width)
}

/// A stroke `half_width` either side of the line through `points`.
pub(super) fn polyline(points: &[(f64, f64)], half_width: f64) -> Shape {
    let points = points.to_vec();
    Box::new(move |x, y| {
        points
            .windows(2)
            .map(|w| distance_to_segment((x, y), w[0], w[1]))
            .fold(f64::INFINITY, f64::min)
            - half_width
    })
}

/// A stroke `half_width` either side of the boundary of `shape`.
pub(super) fn outline(shape: Shape, half_width: f64) -> Shape {
    Box::new(move |x, y| shape(x, y).abs() - half_width)
}

fn distance_to_segment(p: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let length2 = dx * dx + dy * dy;
    let t = if length2 > 0.0 {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / length2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p.0 - a.0 - t * dx).hypot(p.1 - a.1 - t * dy)
}

/// An image of `width` × `height` pixels showing `extent`, (x1, y1) at its lower left corner as
/// FMI 3.0.2 §2.4.9.1.3 maps it; colours premultiplied by their opacity, all 0…1.
pub(super) struct Canvas {
    width: usize,
    height: usize,
    extent: Extent,
    pixels: Vec<[f64; 4]>,
}

impl Canvas {
    pub(super) fn new(width: u32, height: u32, extent: Extent) -> Self {
        let (width, height) = (width as usize, height as usize);
        Canvas {
            width,
            height,
            extent,
            pixels: vec![[0.0; 4]; width * height],
        }
    }

    /// Paints `shape` in one colour.
    pub(super) fn fill(&mut self, shape: impl Fn(f64, f64) -> f64, colour: Rgb) {
        self.paint(shape, |_, _| colour);
    }

    /// Paints `shape` over what is there, in the colour `colour` gives each point; the edge is
    /// blended over one pixel.
    pub(super) fn paint(&mut self, shape: impl Fn(f64, f64) -> f64, colour: impl Fn(f64, f64) -> Rgb) {
        let Extent { x1, y1, x2, y2 } = self.extent;
        let (dx, dy) = ((x2 - x1) / self.width as f64, (y2 - y1) / self.height as f64);
        for row in 0..self.height {
            let y = y2 - (row as f64 + 0.5) * dy;
            for column in 0..self.width {
                let x = x1 + (column as f64 + 0.5) * dx;
                let coverage = (0.5 - shape(x, y) / dx).clamp(0.0, 1.0);
                if coverage == 0.0 {
                    continue;
                }
                let Rgb(r, g, b) = colour(x, y);
                let pixel = &mut self.pixels[row * self.width + column];
                for (channel, value) in pixel.iter_mut().zip([r, g, b, 255]) {
                    *channel = f64::from(value) / 255.0 * coverage + *channel * (1.0 - coverage);
                }
            }
        }
    }

    /// The pixels as 8-bit RGBA, not premultiplied, rows top to bottom.
    pub(super) fn rgba8(&self) -> Vec<u8> {
        let to_byte = |v: f64| (v * 255.0).round().clamp(0.0, 255.0) as u8;
        self.pixels
            .iter()
            .flat_map(|&[r, g, b, a]| {
                if a > 0.0 {
                    [to_byte(r / a), to_byte(g / a), to_byte(b / a), to_byte(a)]
                } else {
                    [0; 4]
                }
            })
            .collect()
    }
}

// ---------------------------------------------------------------------------------------------
// PNG (ISO/IEC 15948, W3C PNG second edition)

const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

/// A PNG of `width` × `height` 8-bit RGBA pixels given row by row from the top: the signature,
/// `IHDR`, one `IDAT` (zlib stream of the rows, each with filter type 0, None) and `IEND`.
pub(super) fn png(width: u32, height: u32, rgba: &[u8]) -> Result<Vec<u8>, String> {
    let row_bytes = width as usize * 4;
    if width == 0 || height == 0 || rgba.len() != row_bytes * height as usize {
        return Err(format!("{} bytes are no {width} x {height} RGBA image", rgba.len()));
    }
    let mut header = Vec::with_capacity(13);
    header.extend(width.to_be_bytes());
    header.extend(height.to_be_bytes());
    // Bit depth 8, colour type 6 (RGBA), compression 0 (deflate), filter method 0, no interlace.
    header.extend([8, 6, 0, 0, 0]);

    let mut zlib = ZlibEncoder::new(Vec::new(), Compression::best());
    for row in rgba.chunks(row_bytes) {
        zlib.write_all(&[0])
            .and_then(|_| zlib.write_all(row))
            .map_err(|e| format!("compressing the pixels: {e}"))?;
    }
    let data = zlib.finish().map_err(|e| format!("compressing the pixels: {e}"))?;

    let mut file = PNG_SIGNATURE.to_vec();
    chunk(&mut file, b"IHDR", &header);
    chunk(&mut file, b"IDAT", &data);
    chunk(&mut file, b"IEND", &[]);
    Ok(file)
}

/// Appends a chunk: length, type, data, and the CRC-32 of type and data.
fn chunk(file: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    let length = u32::try_from(data.len()).expect("a PNG chunk holds less than 2^31 bytes");
    let mut crc = crc32fast::Hasher::new();
    crc.update(kind);
    crc.update(data);
    file.extend(length.to_be_bytes());
    file.extend(kind);
    file.extend(data);
    file.extend(crc.finalize().to_be_bytes());
}

#[cfg(test)]
pub(super) mod tests {
    use std::io::Read;

    use super::*;

    /// CRC-32 bit by bit (ISO 3309, reflected polynomial 0xEDB88320), independent of crc32fast.
    fn crc32_reference(bytes: &[u8]) -> u32 {
        let mut crc = !0u32;
        for &byte in bytes {
            crc ^= u32::from(byte);
            for _ in 0..8 {
                crc = if crc & 1 == 1 {
                    (crc >> 1) ^ 0xEDB8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }

    /// The chunks of a PNG file (type, data), each CRC checked.
    fn chunks(file: &[u8]) -> Vec<([u8; 4], Vec<u8>)> {
        assert_eq!(file[..8], PNG_SIGNATURE);
        let mut rest = &file[8..];
        let mut found = Vec::new();
        while !rest.is_empty() {
            let length = u32::from_be_bytes(rest[..4].try_into().unwrap()) as usize;
            let kind: [u8; 4] = rest[4..8].try_into().unwrap();
            let data = &rest[8..8 + length];
            let crc = u32::from_be_bytes(rest[8 + length..12 + length].try_into().unwrap());
            assert_eq!(crc, crc32_reference(&rest[4..8 + length]), "CRC of {:?}", kind);
            found.push((kind, data.to_vec()));
            rest = &rest[12 + length..];
        }
        found
    }

    /// The pixels of a PNG written by [`png`]: RGBA rows with filter type 0.
    pub(in crate::kit) fn decode(file: &[u8]) -> (u32, u32, Vec<u8>) {
        let chunks = chunks(file);
        let kinds: Vec<&[u8; 4]> = chunks.iter().map(|(kind, _)| kind).collect();
        assert_eq!(kinds, [b"IHDR", b"IDAT", b"IEND"]);
        let header = &chunks[0].1;
        let width = u32::from_be_bytes(header[..4].try_into().unwrap());
        let height = u32::from_be_bytes(header[4..8].try_into().unwrap());
        assert_eq!(header[8..], [8, 6, 0, 0, 0]);
        let mut raw = Vec::new();
        flate2::read::ZlibDecoder::new(chunks[1].1.as_slice())
            .read_to_end(&mut raw)
            .unwrap();
        let row_bytes = width as usize * 4 + 1;
        assert_eq!(raw.len(), row_bytes * height as usize);
        let mut pixels = Vec::new();
        for row in raw.chunks(row_bytes) {
            assert_eq!(row[0], 0, "filter type");
            pixels.extend(&row[1..]);
        }
        (width, height, pixels)
    }

    #[test]
    fn png_round_trips_its_pixels_with_correct_crcs() {
        let pixels: Vec<u8> = (0..3 * 2 * 4).map(|i| (i * 37 % 256) as u8).collect();
        let file = png(3, 2, &pixels).unwrap();
        assert_eq!(decode(&file), (3, 2, pixels));
    }

    #[test]
    fn png_ends_with_the_well_known_iend_chunk() {
        // Every PNG ends in these 12 bytes: length 0, "IEND", CRC 0xAE426082.
        let file = png(1, 1, &[1, 2, 3, 4]).unwrap();
        assert_eq!(
            file[file.len() - 12..],
            [0, 0, 0, 0, b'I', b'E', b'N', b'D', 0xAE, 0x42, 0x60, 0x82]
        );
    }

    #[test]
    fn png_refuses_pixels_of_another_size() {
        assert!(png(2, 2, &[0; 12]).is_err());
        assert!(png(0, 1, &[]).is_err());
    }

    /// The bit-by-bit CRC agrees with the check value of CRC-32: "123456789" → 0xCBF43926.
    #[test]
    fn reference_crc_matches_the_standard_check_value() {
        assert_eq!(crc32_reference(b"123456789"), 0xCBF4_3926);
    }
}
