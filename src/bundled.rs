//! Height maps compiled into the binary, so the default job runs from any folder.
//! Sources and licenses: `assets/heightmaps/SOURCES.md`.

use crate::error::Result;
use crate::heightfield::{Convention, HeightField};

/// `rocks_depth.jpg` (Godot demo projects, MIT): 1024x1024, 8-bit, depth convention.
pub const ROCKS_DEPTH_JPG: &[u8] = include_bytes!("../assets/heightmaps/rocks_depth.jpg");

/// The rocks map in the height convention.
pub fn rocks() -> Result<HeightField> {
    HeightField::decode(
        ROCKS_DEPTH_JPG,
        Convention::Depth,
        "rocks_depth.jpg (bundled)",
    )
}
