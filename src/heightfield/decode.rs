//! Height-map files (PNG 8/16-bit, JPEG, OpenEXR) into a [`HeightField`], with the checks
//! that refuse truncated or inconsistent files by name (the `decode` feature).

use super::{Convention, HeightField, MAX_FILE_BYTES, Texels};
use crate::error::{Error, Result};
use image::DynamicImage;
use std::path::Path;

/// What a height-map file's header says, read without decoding the image
/// ([`HeightField::probe`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImageHeader {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Bytes per pixel of the decoded image (e.g. 1 for 8-bit grey, 16 for RGBA f32).
    pub decoded_bytes_per_pixel: u32,
    /// Bytes per texel of the height field it becomes (1, 2 or 4).
    pub texel_bytes: u32,
    /// The file's size in bytes.
    pub file_bytes: u64,
}

/// Opens `path` for reading if it is a regular file of at most [`MAX_FILE_BYTES`]
/// ([`crate::input::open`]): a device (`/dev/zero`), FIFO or folder cannot be
/// size-checked and is refused.
fn open_checked(path: &Path) -> Result<(std::fs::File, u64)> {
    crate::input::open(path, MAX_FILE_BYTES, "an image file")
}

/// Reads a whole image file after [`open_checked`]'s checks (a regular file of at most
/// [`MAX_FILE_BYTES`]).
pub(crate) fn read_checked(path: &Path) -> Result<Vec<u8>> {
    crate::input::read(path, MAX_FILE_BYTES, "an image file")
}

impl HeightField {
    /// Reads the header of a height-map file (size and pixel format) without decoding
    /// it, after checking that it is a regular file of at most [`MAX_FILE_BYTES`]; lets
    /// a caller bound a load's memory before it happens.
    pub fn probe(path: &Path) -> Result<ImageHeader> {
        let (file, file_bytes) = open_checked(path)?;
        let image_error = |message: String| Error::Image {
            path: path.to_owned(),
            message,
        };
        let mut reader = std::io::BufReader::new(file);
        let is_exr = std::io::BufRead::fill_buf(&mut reader)
            .map(|head| image::guess_format(head).ok() == Some(image::ImageFormat::OpenExr))
            .unwrap_or(false);
        if is_exr {
            // The part the height is read from (crate::exr_height's rule), by its header.
            let part = crate::exr_height::choose(reader).map_err(image_error)?;
            let side = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
            let by_image = part.parts == 1 && part.channels == crate::exr_height::Channels::Rgb;
            return Ok(ImageHeader {
                width: side(part.width),
                height: side(part.height),
                // image decodes a single-part RGB file as RGBA f32; the rest is read as
                // one f32 per texel.
                decoded_bytes_per_pixel: if by_image { 16 } else { 4 },
                texel_bytes: 4,
                file_bytes,
            });
        }
        let reader = image::ImageReader::new(reader)
            .with_guessed_format()
            .map_err(|e| image_error(e.to_string()))?;
        if reader.format().is_none() {
            return Err(image_error("not a PNG, JPEG or OpenEXR image".into()));
        }
        let format = reader.format();
        let decoder = reader.into_decoder().map_err(|e| {
            image_error(match (format, png_header_size(path)) {
                (Some(image::ImageFormat::Png), Some((w, h))) => format!(
                    "cannot decode: the header says {w}x{h} pixels, more than the PNG decoder \
                     takes ({e}); a height map may have at most the device's \
                     maxImageDimension2D pixels per side"
                ),
                _ => format!("cannot decode: {e}"),
            })
        })?;
        let (width, height) = image::ImageDecoder::dimensions(&decoder);
        let color = image::ImageDecoder::color_type(&decoder);
        let texel_bytes = match color.bytes_per_pixel() / color.channel_count().max(1) {
            1 => 1,
            2 => 2,
            _ => 4,
        };
        Ok(ImageHeader {
            width,
            height,
            decoded_bytes_per_pixel: u32::from(color.bytes_per_pixel()),
            texel_bytes,
            file_bytes,
        })
    }

    /// Loads PNG (8/16-bit), JPEG or OpenEXR; `convention` says how the file encodes heights.
    /// Only a regular file of at most [`MAX_FILE_BYTES`] is read (see [`HeightField::probe`]);
    /// an image whose decoded size exceeds the decoder's limit is refused with its size.
    pub fn load(path: &Path, convention: Convention) -> Result<Self> {
        let bytes = read_checked(path)?;
        png_palette_complete(&bytes).map_err(|message| Error::Image {
            path: path.to_owned(),
            message,
        })?;
        if image::guess_format(&bytes).ok() == Some(image::ImageFormat::Jpeg) {
            jpeg_complete(&bytes).map_err(|message| Error::Image {
                path: path.to_owned(),
                message,
            })?;
        }
        let reader = image::ImageReader::new(std::io::Cursor::new(&bytes))
            .with_guessed_format()
            .map_err(|e| Error::Image {
                path: path.to_owned(),
                message: e.to_string(),
            })?;
        if reader.format().is_none() {
            return Err(Error::Image {
                path: path.to_owned(),
                message: "not a PNG, JPEG or OpenEXR image".into(),
            });
        }
        if reader.format() == Some(image::ImageFormat::OpenExr) {
            let image_error = |message: String| Error::Image {
                path: path.to_owned(),
                message,
            };
            let part =
                crate::exr_height::choose(std::io::Cursor::new(&bytes)).map_err(image_error)?;
            if part.parts > 1 || part.channels != crate::exr_height::Channels::Rgb {
                let values = crate::exr_height::read(&bytes, &part).map_err(image_error)?;
                let invert = convention == Convention::Depth;
                let heights = values
                    .into_iter()
                    .map(|v| if invert { 1.0 - v } else { v })
                    .collect();
                let side = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
                let label = path.display().to_string();
                let mut field =
                    Self::from_heights(side(part.width), side(part.height), heights, &label)
                        .map_err(|e| match e {
                            Error::InvalidInput { message, .. } => {
                                image_error(format!("{}: {message}", part.describe()))
                            }
                            other => other,
                        })?;
                if part.parts > 1 {
                    field.part = Some(part.describe());
                }
                return Ok(field);
            }
        }
        let decoded = reader.decode();
        let image = decoded.map_err(|e| {
            let message = match (&e, Self::probe(path)) {
                (image::ImageError::Limits(_), Ok(h)) => format!(
                    "cannot decode: the header says {}x{} pixels of {} bytes ({:.1} MiB \
                     decoded), above the decoder's memory limit ({e})",
                    h.width,
                    h.height,
                    h.decoded_bytes_per_pixel,
                    f64::from(h.width) * f64::from(h.height) * f64::from(h.decoded_bytes_per_pixel)
                        / f64::from(1u32 << 20)
                ),
                _ => format!("cannot decode: {e}"),
            };
            Error::Image {
                path: path.to_owned(),
                message,
            }
        })?;
        let label = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| path.display().to_string());
        Self::from_image(image, convention, label).map_err(|e| match e {
            Error::InvalidInput { message, .. } => Error::Image {
                path: path.to_owned(),
                message,
            },
            other => other,
        })
    }

    /// Decodes an in-memory PNG, JPEG or OpenEXR file (e.g. a bundled map).
    pub fn decode(bytes: &[u8], convention: Convention, label: &str) -> Result<Self> {
        png_palette_complete(bytes).map_err(|message| Error::Image {
            path: label.into(),
            message,
        })?;
        if image::guess_format(bytes).ok() == Some(image::ImageFormat::Jpeg) {
            jpeg_complete(bytes).map_err(|message| Error::Image {
                path: label.into(),
                message,
            })?;
        }
        let image = image::load_from_memory(bytes).map_err(|e| Error::Image {
            path: label.into(),
            message: format!("cannot decode: {e}"),
        })?;
        Self::from_image(image, convention, label.to_owned())
    }

    /// Converts a decoded image, keeping its precision.
    pub fn from_image(image: DynamicImage, convention: Convention, label: String) -> Result<Self> {
        let (width, height) = (image.width(), image.height());
        if width == 0 || height == 0 {
            return Err(Error::invalid(&label, "the image has no pixels"));
        }
        let invert = convention == Convention::Depth;
        let texels = match image {
            DynamicImage::ImageLuma8(img) => Texels::R8(
                img.into_raw()
                    .into_iter()
                    .map(|v| if invert { 255 - v } else { v })
                    .collect(),
            ),
            DynamicImage::ImageLuma16(img) => Texels::R16(
                img.into_raw()
                    .into_iter()
                    .map(|v| if invert { 65535 - v } else { v })
                    .collect(),
            ),
            DynamicImage::ImageLumaA8(_)
            | DynamicImage::ImageRgb8(_)
            | DynamicImage::ImageRgba8(_) => {
                let rgb = image.to_rgb8();
                Texels::R8(
                    rgb.pixels()
                        .map(|p| {
                            let l = luminance8(p.0);
                            if invert { 255 - l } else { l }
                        })
                        .collect(),
                )
            }
            DynamicImage::ImageLumaA16(_)
            | DynamicImage::ImageRgb16(_)
            | DynamicImage::ImageRgba16(_) => {
                let rgb = image.to_rgb16();
                Texels::R16(
                    rgb.pixels()
                        .map(|p| {
                            let l = luminance16(p.0);
                            if invert { 65535 - l } else { l }
                        })
                        .collect(),
                )
            }
            other => {
                // Float images (OpenEXR): luminance in f32, must lie in [0, 1].
                let rgb = other.to_rgb32f();
                let mut values = Vec::with_capacity(rgb.len() / 3);
                for p in rgb.pixels() {
                    let [r, g, b] = p.0;
                    let l = if r == g && g == b {
                        r
                    } else {
                        0.2126 * r + 0.7152 * g + 0.0722 * b
                    };
                    if !l.is_finite() || !(0.0..=1.0).contains(&l) {
                        return Err(Error::invalid(
                            &label,
                            format!("float height {l} outside [0, 1]"),
                        ));
                    }
                    values.push(if invert { 1.0 - l } else { l });
                }
                Texels::R32F(values)
            }
        };
        Ok(HeightField {
            width,
            height,
            texels,
            label,
            part: None,
        })
    }
}

/// Checks that a JPEG file is complete: the image decoder fills the missing part of a
/// truncated JPEG with grey instead of failing, so a file cut anywhere after its header
/// would load as a valid map. Complete files end their last scan with the end-of-image
/// marker `FF D9`; neither it nor a scan marker can occur inside entropy-coded data
/// (`FF` is stuffed there), so "an `FF D9` after the last `FF DA`" is the test.
/// Refuses a JPEG that ends early: without an end-of-image marker after its last scan,
/// or with one appended to data that was cut (the case image's lenient decoder accepts,
/// filling what is missing with grey or leaving a scan half applied).
///
/// The second case is found with zune-jpeg (the decoder image uses) in strict mode: the
/// file is decoded as it is and with 32 bytes of one bits inserted before its final
/// end-of-image marker. A complete last scan ends before the marker, so the inserted
/// bits are never read and both decodes agree; a cut scan reads on into them (they are
/// not a valid Huffman code, or decode to other values), so the second decode fails or
/// differs. A file the strict decoder refuses as it is gets no verdict here: the
/// caller's decode accepts or names it.
fn jpeg_complete(bytes: &[u8]) -> std::result::Result<(), String> {
    let last = |marker: u8| bytes.windows(2).rposition(|w| w == [0xFF, marker]);
    let end = match (last(0xDA), last(0xD9)) {
        (Some(scan), Some(end)) if end > scan => end,
        (None, _) => return Err("truncated JPEG: no image data (no start-of-scan marker)".into()),
        _ => return Err("truncated JPEG: the data ends before the end-of-image marker".into()),
    };
    let decode = |data: &[u8]| {
        use zune_jpeg::zune_core::{bytestream::ZCursor, colorspace::ColorSpace};
        let options = zune_jpeg::zune_core::options::DecoderOptions::default()
            .jpeg_set_out_colorspace(ColorSpace::Luma)
            .set_strict_mode(true);
        zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(data), options).decode()
    };
    let Ok(plain) = decode(bytes) else {
        return Ok(());
    };
    // 0xFF 0x00 is a stuffed 0xFF data byte: eight one bits.
    let ones = [0xFF, 0x00].repeat(32);
    match decode(&[&bytes[..end], &ones, &bytes[end..]].concat()) {
        Ok(probed) if probed == plain => Ok(()),
        _ => Err(
            "truncated JPEG: the image data ends early (an end-of-image marker \
                  follows data that was cut)"
                .into(),
        ),
    }
}

/// The width and height in a PNG file's header (its first chunk, IHDR), read without a
/// decoder (one that refuses the size gives no size).
fn png_header_size(path: &Path) -> Option<(u32, u32)> {
    let (mut file, _) = open_checked(path).ok()?;
    let mut head = [0u8; 24];
    std::io::Read::read_exact(&mut file, &mut head).ok()?;
    let word = |at: usize| u32::from_be_bytes([head[at], head[at + 1], head[at + 2], head[at + 3]]);
    (&head[12..16] == b"IHDR").then(|| (word(16), word(20)))
}

/// Refuses a palette PNG with a pixel whose index is past the end of its palette (the
/// decoder would make it black); other files pass. Reads the raw indices (at most one
/// byte per pixel, less than the decoded image).
pub(crate) fn png_palette_complete(bytes: &[u8]) -> std::result::Result<(), String> {
    if image::guess_format(bytes).ok() != Some(image::ImageFormat::Png) {
        return Ok(());
    }
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::IDENTITY);
    // Not decodable here: the image decoder's own error names the cause.
    let Ok(mut reader) = decoder.read_info() else {
        return Ok(());
    };
    let info = reader.info();
    if info.color_type != png::ColorType::Indexed {
        return Ok(());
    }
    let entries = info.palette.as_ref().map_or(0, |p| p.len() / 3);
    let bits = info.bit_depth as u32;
    let (width, height) = (info.width as usize, info.height as usize);
    let Some(size) = reader.output_buffer_size() else {
        return Ok(());
    };
    let mut buf = vec![0u8; size];
    let Ok(frame) = reader.next_frame(&mut buf) else {
        return Ok(());
    };
    let per_byte = (8 / bits.max(1)) as usize;
    for y in 0..height {
        let row = &buf[y * frame.line_size..(y + 1) * frame.line_size];
        for x in 0..width {
            let byte = row[x / per_byte];
            let shift = 8 - bits as usize * (x % per_byte + 1);
            let index = (byte >> shift) as usize & ((1usize << bits) - 1);
            if index >= entries {
                return Err(format!(
                    "pixel ({x}, {y}) has palette index {index}, past the palette's {entries} \
                     entries"
                ));
            }
        }
    }
    Ok(())
}

fn luminance8([r, g, b]: [u8; 3]) -> u8 {
    if r == g && g == b {
        r
    } else {
        (0.2126 * r as f32 + 0.7152 * g as f32 + 0.0722 * b as f32).round() as u8
    }
}

fn luminance16([r, g, b]: [u16; 3]) -> u16 {
    if r == g && g == b {
        r
    } else {
        (0.2126 * r as f32 + 0.7152 * g as f32 + 0.0722 * b as f32).round() as u16
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ash::vk;

    fn asset(name: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("assets/heightmaps")
            .join(name)
    }

    #[test]
    fn loads_bundled_maps_at_their_precision() {
        let rocks = HeightField::load(&asset("rocks_depth.jpg"), Convention::Depth).unwrap();
        assert_eq!((rocks.width(), rocks.height()), (1024, 1024));
        assert_eq!(rocks.format(), vk::Format::R8_UNORM);
        // SOURCES.md: mean height 0.52 after inverting.
        assert!((rocks.mean() - 0.52).abs() < 0.02, "{}", rocks.mean());

        let mountains =
            HeightField::load(&asset("mountains_height16.png"), Convention::Height).unwrap();
        assert_eq!((mountains.width(), mountains.height()), (1025, 1025));
        assert_eq!(mountains.format(), vk::Format::R16_UNORM);
        // Raw mean 0.084; SOURCES.md's 0.13 is relative to the map's maximum (0.668).
        assert!(
            (mountains.mean() - 0.0844).abs() < 0.001,
            "{}",
            mountains.mean()
        );

        let shapes = HeightField::load(&asset("shapes_depth.png"), Convention::Depth).unwrap();
        assert_eq!((shapes.width(), shapes.height()), (348, 348));
        let bricks = HeightField::load(&asset("bricks_depth.jpg"), Convention::Depth).unwrap();
        assert_eq!((bricks.width(), bricks.height()), (1000, 1000));
        // Measured 0.827 (PIL agrees); SOURCES.md's 0.76 was computed differently.
        assert!((bricks.mean() - 0.827).abs() < 0.002, "{}", bricks.mean());
    }

    #[test]
    fn depth_inversion_is_exact() {
        let img = image::GrayImage::from_raw(2, 1, vec![0, 200]).unwrap();
        let h = HeightField::from_image(img.into(), Convention::Depth, "t".into()).unwrap();
        assert_eq!(h.texels(), &Texels::R8(vec![255, 55]));
        let img16 = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(1, 1, vec![1u16]).unwrap();
        let h = HeightField::from_image(img16.into(), Convention::Depth, "t".into()).unwrap();
        assert_eq!(h.texels(), &Texels::R16(vec![65534]));
    }

    #[test]
    fn bad_files_name_the_file() {
        let err = HeightField::load(Path::new("/nonexistent/x.png"), Convention::Height)
            .unwrap_err()
            .to_string();
        assert!(err.contains("/nonexistent/x.png"), "{err}");
        let dir = std::env::temp_dir().join("dispmap-heightfield-test");
        std::fs::create_dir_all(&dir).unwrap();
        let junk = dir.join("junk.png");
        std::fs::write(&junk, b"definitely not an image").unwrap();
        let err = HeightField::load(&junk, Convention::Height)
            .unwrap_err()
            .to_string();
        assert!(err.contains("junk.png"), "{err}");
    }

    #[test]
    fn truncated_files_are_rejected_by_name() {
        let dir = std::env::temp_dir().join(format!("dispmap-truncated-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for name in [
            "rocks_depth.jpg",
            "bricks_depth.jpg",
            "mountains_height16.png",
        ] {
            let bytes = std::fs::read(asset(name)).unwrap();
            // A JPEG cut by 2 bytes loses its end-of-image marker.
            let last = if name.ends_with(".jpg") {
                2
            } else {
                bytes.len() / 3
            };
            for cut in [bytes.len() / 2, 400, bytes.len() - last] {
                let path = dir.join(format!("cut{cut}_{name}"));
                std::fs::write(&path, &bytes[..cut]).unwrap();
                let Err(err) = HeightField::load(&path, Convention::Height) else {
                    panic!("{name} cut to {cut} bytes loads");
                };
                let err = err.to_string();
                assert!(err.contains(&format!("cut{cut}_{name}")), "{err}");
                let Err(err) = HeightField::decode(&bytes[..cut], Convention::Height, name) else {
                    panic!("{name} cut to {cut} bytes decodes");
                };
                assert!(err.to_string().contains(name), "{err}");
            }
            // The complete file still loads.
            HeightField::decode(&bytes, Convention::Height, name).unwrap();
        }
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn openexr_loads_as_float() {
        let dir = std::env::temp_dir().join("dispmap-heightfield-exr");
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("ramp.exr");
        let img = image::Rgb32FImage::from_fn(3, 5, |x, y| {
            let v = (x + 3 * y) as f32 / 14.0;
            image::Rgb([v, v, v])
        });
        img.save(&path).unwrap();
        let h = HeightField::load(&path, Convention::Height).unwrap();
        assert_eq!(
            (h.width(), h.height(), h.format()),
            (3, 5, vk::Format::R32_SFLOAT)
        );
        assert_eq!(h.texel(2, 4), 1.0);
        assert_eq!(h.texel(1, 0), 1.0 / 14.0);
        let d = HeightField::load(&path, Convention::Depth).unwrap();
        assert_eq!(d.texel(1, 0), 1.0 - 1.0 / 14.0);
    }

    #[test]
    fn rgb_maps_become_luminance() {
        let img = image::RgbImage::from_raw(2, 1, vec![10, 10, 10, 255, 0, 0]).unwrap();
        let h = HeightField::from_image(img.into(), Convention::Height, "t".into()).unwrap();
        // Equal channels are exact; others use Rec. 709 weights.
        assert_eq!(h.texels(), &Texels::R8(vec![10, 54]));
    }

    #[test]
    fn float_maps_out_of_range_are_rejected() {
        assert!(HeightField::from_heights(1, 1, vec![1.5], "t").is_err());
        assert!(HeightField::from_heights(1, 1, vec![f32::NAN], "t").is_err());
        assert!(HeightField::from_heights(2, 1, vec![0.5], "t").is_err());
        let h = HeightField::from_heights(1, 1, vec![0.25], "t").unwrap();
        assert_eq!(h.texel(0, 0), 0.25);
        assert_eq!(h.format(), vk::Format::R32_SFLOAT);
    }

    /// Single-channel OpenEXR (`Y` or `R` only) loads exactly; a value outside [0, 1]
    /// is named.
    #[test]
    fn single_channel_exr_loads() {
        use exr::prelude::{Image, SpecificChannels, WritableImage as _};
        let dir = std::env::temp_dir().join(format!("dispmap-exr1-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (name, scale) in [("Y", 1.0f32), ("R", 1.0), ("Y", 3.0)] {
            let pixels = SpecificChannels::build()
                .with_channel(name)
                .with_pixel_fn(move |p| (scale * (p.0 + 3 * p.1) as f32 / 8.0,));
            let path = dir.join(format!("{name}{scale}.exr"));
            Image::from_channels((3, 2), pixels)
                .write()
                .to_file(&path)
                .unwrap();
            let header = HeightField::probe(&path).unwrap();
            assert_eq!((header.width, header.height), (3, 2));
            match HeightField::load(&path, Convention::Height) {
                Ok(field) => {
                    assert_eq!(scale, 1.0);
                    assert_eq!(field.format(), vk::Format::R32_SFLOAT);
                    assert_eq!(field.texel(2, 1), 5.0 / 8.0);
                    let depth = HeightField::load(&path, Convention::Depth).unwrap();
                    assert_eq!(depth.texel(2, 1), 3.0 / 8.0);
                }
                Err(e) => {
                    assert_eq!(scale, 3.0, "{e}");
                    let e = e.to_string();
                    assert!(e.contains("Y3.exr") && e.contains("outside [0, 1]"), "{e}");
                }
            }
        }
        // Not a regular file: refused before reading.
        let err = HeightField::load(&dir, Convention::Height)
            .unwrap_err()
            .to_string();
        assert!(err.contains("is a folder"), "{err}");
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_cut_jpeg_is_refused_even_with_an_end_marker_appended() {
        // A baseline (sequential) JPEG, as most encoders write; the bundled maps are
        // progressive.
        let gradient = image::GrayImage::from_fn(96, 80, |x, y| image::Luma([(x * 2 + y) as u8]));
        let mut baseline = Vec::new();
        image::DynamicImage::ImageLuma8(gradient)
            .write_with_encoder(image::codecs::jpeg::JpegEncoder::new_with_quality(
                &mut baseline,
                90,
            ))
            .unwrap();
        let rocks = std::fs::read(asset("rocks_depth.jpg")).unwrap();
        for (name, whole) in [("baseline", &baseline), ("progressive", &rocks)] {
            HeightField::decode(whole, Convention::Height, name).unwrap();
            for cut in [whole.len() * 3 / 10, whole.len() * 6 / 10, whole.len() - 8] {
                let cut = [&whole[..cut], &[0xFF, 0xD9][..]].concat();
                let err = HeightField::decode(&cut, Convention::Height, name)
                    .unwrap_err()
                    .to_string();
                assert!(
                    err.contains(name) && err.contains("data that was cut"),
                    "{name} cut at {} of {}: {err}",
                    cut.len() - 2,
                    whole.len()
                );
            }
        }
    }
}
