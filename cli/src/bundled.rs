//! Height maps compiled into the binary, so the default job and the benchmark run from
//! any folder. Sources and licenses: `assets/heightmaps/SOURCES.md`.

use dispmap::error::{Error, Result};
use dispmap::heightfield::{Convention, HeightField};

/// `rocks_depth.jpg` (Godot demo projects, MIT): 1024x1024, 8-bit, depth convention.
pub const ROCKS_DEPTH_JPG: &[u8] = include_bytes!("../../assets/heightmaps/rocks_depth.jpg");

/// `bricks_depth.jpg` (Godot demo projects, MIT): 1000x1000, 8-bit, depth convention.
pub const BRICKS_DEPTH_JPG: &[u8] = include_bytes!("../../assets/heightmaps/bricks_depth.jpg");

/// `mountains_height16.png` (Diligent Samples, Apache-2.0): 1025x1025, 16-bit, height
/// convention.
pub const MOUNTAINS_HEIGHT16_PNG: &[u8] =
    include_bytes!("../../assets/heightmaps/mountains_height16.png");

/// The names [`by_name`] knows, in the DIG paper's order of height distributions:
/// roughly uniform, top heavy, bottom heavy.
pub const NAMES: [&str; 3] = ["rocks", "bricks", "mountains"];

/// The rocks map in the height convention.
pub fn rocks() -> Result<HeightField> {
    HeightField::decode(
        ROCKS_DEPTH_JPG,
        Convention::Depth,
        "rocks_depth.jpg (bundled)",
    )
}

/// The bricks map (top heavy) in the height convention.
pub fn bricks() -> Result<HeightField> {
    HeightField::decode(
        BRICKS_DEPTH_JPG,
        Convention::Depth,
        "bricks_depth.jpg (bundled)",
    )
}

/// The mountains map (bottom heavy, 16-bit) in the height convention.
pub fn mountains() -> Result<HeightField> {
    HeightField::decode(
        MOUNTAINS_HEIGHT16_PNG,
        Convention::Height,
        "mountains_height16.png (bundled)",
    )
}

/// A bundled map by its short name (one of [`NAMES`]); the error names `option`.
pub fn by_name(name: &str, option: &str) -> Result<HeightField> {
    match name {
        "rocks" => rocks(),
        "bricks" => bricks(),
        "mountains" => mountains(),
        other => Err(Error::invalid(
            option,
            format!(
                "unknown bundled map '{other}' (known: {})",
                NAMES.join(", ")
            ),
        )),
    }
}
