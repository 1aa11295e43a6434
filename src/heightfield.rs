//! Height fields: conventions, texels and the values the GPU and the reference see;
//! loading them from files (PNG, JPEG, OpenEXR) is the `decode` feature's (on by default;
//! an engine that hands over its own texels uses [`HeightField::from_texels`]).
//!
//! A [`HeightField`] always stores *heights* (`1` = the macro surface, `0` = the deepest
//! point), whatever convention the file used: a depth map is inverted exactly at load
//! time (`255 - v`, `65535 - v`, `1 - v`), so the GPU texture and the CPU reference read
//! the same numbers. The precision of the file is kept: 8-bit files become `R8_UNORM`,
//! 16-bit files `R16_UNORM`, float files (OpenEXR) `R32_SFLOAT`. RGB files are reduced
//! to luminance (Rec. 709 weights); maps with three equal channels are read exactly.
//!
//! Texel `(i, j)` sits at `uv = ((i + 0.5) / W, (j + 0.5) / H)`; row 0 is the first row of
//! the file (the top of the picture), which is `v = 0`.

use crate::error::{Error, Result};
use ash::vk;

/// How a file encodes heights.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "lowercase"))]
pub enum Convention {
    /// White is high (the macro surface), black is the deepest point.
    Height,
    /// White is deep, black is the macro surface.
    Depth,
}

impl std::str::FromStr for Convention {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "height" => Ok(Convention::Height),
            "depth" => Ok(Convention::Depth),
            other => Err(Error::invalid(
                "convention",
                format!("'{other}' is not one of: height, depth"),
            )),
        }
    }
}

/// How UVs outside `[0, 1]²` are treated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "lowercase"))]
pub enum Addressing {
    /// Tiled surface: the height field repeats.
    Repeat,
    /// A single decal: a ray that leaves `[0, 1]²` before it hits is discarded.
    Clamp,
}

/// Texel storage at the file's precision (already in the height convention).
#[derive(Clone, Debug, PartialEq)]
pub enum Texels {
    /// 8-bit UNORM.
    R8(Vec<u8>),
    /// 16-bit UNORM.
    R16(Vec<u16>),
    /// 32-bit float, expected in `[0, 1]`.
    R32F(Vec<f32>),
}

/// A height field in the height convention, at the precision it was loaded with.
#[derive(Clone, Debug, PartialEq)]
pub struct HeightField {
    width: u32,
    height: u32,
    texels: Texels,
    label: String,
    /// Which part of a multi-part OpenEXR file the heights came from.
    part: Option<String>,
}

/// The largest height-map file read (4 GiB): a bigger one is refused before reading.
pub const MAX_FILE_BYTES: u64 = 1 << 32;

#[cfg(feature = "decode")]
mod decode;
#[cfg(feature = "decode")]
pub use decode::ImageHeader;
#[cfg(feature = "decode")]
pub(crate) use decode::{png_palette_complete, read_checked};

impl HeightField {
    /// A height field from texels the caller already holds (an engine that loads its own
    /// textures; no file decoding involved, so it is there without the `decode`
    /// feature). The texels are *heights* (1 = the macro surface, 0 = the deepest point;
    /// a depth map is inverted by the caller, `255 - v`, `65535 - v`, `1 - v`), row by
    /// row from row 0 (`v = 0`), tightly packed, at the precision given: [`Texels::R8`]
    /// and [`Texels::R16`] are uploaded as they are (`R8_UNORM`, `R16_UNORM`: every value
    /// is valid), [`Texels::R32F`] as `R32_SFLOAT` and must be finite and in `[0, 1]`.
    /// `label` names the map in errors (a size that does not match the texel count, a
    /// bad float with its texel) and in reports.
    pub fn from_texels(width: u32, height: u32, texels: Texels, label: &str) -> Result<Self> {
        let count = match &texels {
            Texels::R8(v) => v.len(),
            Texels::R16(v) => v.len(),
            Texels::R32F(v) => v.len(),
        };
        let expected = (width as usize).checked_mul(height as usize);
        if width == 0 || height == 0 || expected != Some(count) {
            return Err(Error::invalid(
                label,
                format!("{count} texels do not make a {width}x{height} height field"),
            ));
        }
        if let Texels::R32F(values) = &texels
            && let Some(k) = values
                .iter()
                .position(|v| !v.is_finite() || !(0.0..=1.0).contains(v))
        {
            return Err(Error::invalid(
                label,
                format!(
                    "height {} outside [0, 1] at texel ({}, {})",
                    values[k],
                    k % width as usize,
                    k / width as usize
                ),
            ));
        }
        Ok(HeightField {
            width,
            height,
            texels,
            label: label.to_owned(),
            part: None,
        })
    }

    /// A float height field from values in the height convention (tests, procedural
    /// maps): [`HeightField::from_texels`] with [`Texels::R32F`].
    pub fn from_heights(width: u32, height: u32, values: Vec<f32>, label: &str) -> Result<Self> {
        Self::from_texels(width, height, Texels::R32F(values), label)
    }

    /// A height field sampled from `f(u, v)` at texel centres.
    pub fn from_fn(
        width: u32,
        height: u32,
        label: &str,
        f: impl Fn(f32, f32) -> f32,
    ) -> Result<Self> {
        let values = (0..height)
            .flat_map(|j| (0..width).map(move |i| (i, j)))
            .map(|(i, j)| {
                f(
                    (i as f32 + 0.5) / width as f32,
                    (j as f32 + 0.5) / height as f32,
                )
            })
            .collect();
        Self::from_heights(width, height, values, label)
    }

    /// Width in texels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in texels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Where the field came from (a file name or a procedural label).
    pub fn label(&self) -> &str {
        &self.label
    }

    /// The part of a multi-part OpenEXR file the heights were read from (`part 1
    /// 'height' of 2 (channel Y)`), chosen by the rule in docs/scenes.md; `None` for any
    /// other file.
    pub fn part(&self) -> Option<&str> {
        self.part.as_deref()
    }

    /// The stored texels.
    pub fn texels(&self) -> &Texels {
        &self.texels
    }

    /// Height of texel `(i, j)` in `[0, 1]`, exactly as the GPU's UNORM/float read sees it.
    #[inline]
    pub fn texel(&self, i: u32, j: u32) -> f32 {
        let k = j as usize * self.width as usize + i as usize;
        match &self.texels {
            Texels::R8(v) => v[k] as f32 / 255.0,
            Texels::R16(v) => v[k] as f32 / 65535.0,
            Texels::R32F(v) => v[k],
        }
    }

    /// The Vulkan format that keeps the stored precision.
    pub fn format(&self) -> vk::Format {
        match self.texels {
            Texels::R8(_) => vk::Format::R8_UNORM,
            Texels::R16(_) => vk::Format::R16_UNORM,
            Texels::R32F(_) => vk::Format::R32_SFLOAT,
        }
    }

    /// Raw bytes for upload, row by row, tightly packed.
    pub fn bytes(&self) -> &[u8] {
        match &self.texels {
            Texels::R8(v) => v,
            Texels::R16(v) => bytemuck::cast_slice(v),
            Texels::R32F(v) => bytemuck::cast_slice(v),
        }
    }

    /// Mean height (reports and tests).
    pub fn mean(&self) -> f64 {
        let n = self.width as usize * self.height as usize;
        let sum: f64 = (0..self.height)
            .flat_map(|j| (0..self.width).map(move |i| (i, j)))
            .map(|(i, j)| self.texel(i, j) as f64)
            .sum();
        sum / n as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texels_keep_their_precision() {
        let r8 = HeightField::from_texels(2, 1, Texels::R8(vec![0, 255]), "host r8").unwrap();
        assert_eq!(r8.format(), vk::Format::R8_UNORM);
        assert_eq!((r8.texel(0, 0), r8.texel(1, 0)), (0.0, 1.0));
        assert_eq!(r8.label(), "host r8");
        let r16 =
            HeightField::from_texels(1, 2, Texels::R16(vec![65535, 32768]), "host r16").unwrap();
        assert_eq!(r16.format(), vk::Format::R16_UNORM);
        assert_eq!(r16.bytes(), &[0xFF, 0xFF, 0x00, 0x80]);
        assert_eq!(r16.texel(0, 1), 32768.0 / 65535.0);
        let f = HeightField::from_texels(1, 1, Texels::R32F(vec![0.25]), "host f32").unwrap();
        assert_eq!(f.format(), vk::Format::R32_SFLOAT);
        assert_eq!(f.texel(0, 0), 0.25);
    }

    #[test]
    fn bad_texels_name_the_input() {
        let message = |r: Result<HeightField>| match r {
            Err(Error::InvalidInput { name, message }) => format!("{name}: {message}"),
            other => panic!("expected InvalidInput, got {other:?}"),
        };
        assert_eq!(
            message(HeightField::from_texels(
                3,
                2,
                Texels::R8(vec![0; 5]),
                "terrain"
            )),
            "terrain: 5 texels do not make a 3x2 height field"
        );
        assert_eq!(
            message(HeightField::from_texels(
                0,
                2,
                Texels::R16(vec![]),
                "terrain"
            )),
            "terrain: 0 texels do not make a 0x2 height field"
        );
        assert!(
            message(HeightField::from_texels(
                u32::MAX,
                u32::MAX,
                Texels::R8(vec![0; 4]),
                "huge"
            ))
            .starts_with("huge: 4 texels do not make a 4294967295x4294967295")
        );
        for (bad, text) in [
            (f32::NAN, "height NaN outside [0, 1] at texel (1, 1)"),
            (f32::INFINITY, "height inf outside [0, 1] at texel (1, 1)"),
            (-0.5, "height -0.5 outside [0, 1] at texel (1, 1)"),
            (1.5, "height 1.5 outside [0, 1] at texel (1, 1)"),
        ] {
            let mut values = vec![0.5; 4];
            values[3] = bad;
            assert_eq!(
                message(HeightField::from_texels(2, 2, Texels::R32F(values), "rock")),
                format!("rock: {text}")
            );
        }
    }
}
