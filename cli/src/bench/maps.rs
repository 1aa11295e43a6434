//! The height maps a run sweeps: bundled or loaded, named for files, and resampled for
//! the map-size sweep.

use dispmap::error::{Error, Result};
use dispmap::heightfield::{HeightField, Texels};
use std::path::Path;

/// A height map of the sweep and the short name used in tables and file names.
#[derive(Clone, Debug)]
pub struct MapSpec {
    /// Short name (`rocks`; a file's stem), used in file names after [`file_stem`].
    pub name: String,
    /// The map, in the height convention.
    pub field: HeightField,
}

impl MapSpec {
    /// A bundled map by name ([`crate::bundled::NAMES`]); the error names `--maps`.
    pub fn bundled(name: &str) -> Result<Self> {
        Ok(MapSpec {
            name: name.to_owned(),
            field: crate::bundled::by_name(name, "--maps")?,
        })
    }

    /// A map file, named after its stem.
    pub fn load(path: &Path, convention: dispmap::heightfield::Convention) -> Result<Self> {
        let field = HeightField::load(path, convention)?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "map".into());
        Ok(MapSpec { name, field })
    }
}

/// The default maps: every bundled map ([`crate::bundled::NAMES`]: rocks, bricks,
/// mountains).
pub fn bundled_maps() -> Result<Vec<MapSpec>> {
    crate::bundled::NAMES
        .iter()
        .map(|name| MapSpec::bundled(name))
        .collect()
}

/// `name` reduced to `[A-Za-z0-9_-]` (other characters become `_`), for file names.
pub fn file_stem(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() { "map".into() } else { s }
}

/// `field` resampled to `width x height` with a Catmull-Rom filter, at its precision
/// (8-bit stays 8-bit, 16-bit 16-bit, float float clamped to `[0, 1]`).
pub fn resample(field: &HeightField, width: u32, height: u32, label: &str) -> Result<HeightField> {
    use image::imageops::{FilterType, resize};
    use image::{DynamicImage, ImageBuffer, Luma};
    if width == 0 || height == 0 {
        return Err(Error::invalid("--sizes", "a map side is zero"));
    }
    let (w, h) = (field.width(), field.height());
    let bad = || Error::invalid(label, "texel count does not match the map size");
    let filter = FilterType::CatmullRom;
    match field.texels() {
        Texels::R8(v) => {
            let img = ImageBuffer::<Luma<u8>, _>::from_raw(w, h, v.clone()).ok_or_else(bad)?;
            let out = resize(&img, width, height, filter);
            HeightField::from_image(
                DynamicImage::ImageLuma8(out),
                dispmap::heightfield::Convention::Height,
                label.to_owned(),
            )
        }
        Texels::R16(v) => {
            let img = ImageBuffer::<Luma<u16>, _>::from_raw(w, h, v.clone()).ok_or_else(bad)?;
            let out = resize(&img, width, height, filter);
            HeightField::from_image(
                DynamicImage::ImageLuma16(out),
                dispmap::heightfield::Convention::Height,
                label.to_owned(),
            )
        }
        Texels::R32F(v) => {
            let img = ImageBuffer::<Luma<f32>, _>::from_raw(w, h, v.clone()).ok_or_else(bad)?;
            let out = resize(&img, width, height, filter);
            let values = out
                .into_raw()
                .into_iter()
                .map(|x| x.clamp(0.0, 1.0))
                .collect();
            HeightField::from_heights(width, height, values, label)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resampling_keeps_the_precision_and_the_range() {
        let rocks = crate::bundled::rocks().unwrap();
        let small = resample(&rocks, 64, 32, "rocks@64").unwrap();
        assert_eq!((small.width(), small.height()), (64, 32));
        assert_eq!(small.format(), rocks.format());
        assert!((small.mean() - rocks.mean()).abs() < 0.02);
        let f = HeightField::from_fn(8, 8, "f", |u, _| u).unwrap();
        let big = resample(&f, 16, 16, "f@16").unwrap();
        assert_eq!(big.format(), f.format());
        let (lo, hi) = (0..16).fold((1.0f32, 0.0f32), |(lo, hi), i| {
            let v = big.texel(i, 3);
            (lo.min(v), hi.max(v))
        });
        assert!(lo >= 0.0 && hi <= 1.0 && hi > lo);
        assert_eq!(file_stem("rocks@256 x/y"), "rocks_256_x_y");
    }
}
