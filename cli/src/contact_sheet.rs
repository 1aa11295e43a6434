//! A contact sheet: frames of the same size side by side in a grid, each with a label
//! band underneath (e.g. the method name and its artifact fraction), text drawn with the
//! bundled DejaVu Sans through plotters (as the benchmark plots are).

use crate::bench::plot::{FAMILY, register_font};
use dispmap::error::{Error, Result};
use plotters::prelude::*;

/// Height of the label band under each tile, pixels.
pub const LABEL_HEIGHT: u32 = 22;
/// Gap between tiles and around the sheet, pixels.
pub const GAP: u32 = 4;

/// One frame of the sheet.
#[derive(Clone, Debug)]
pub struct Tile {
    /// The text under the frame.
    pub label: String,
    /// RGBA8 pixels, `width x height` of the sheet's tiles.
    pub rgba: Vec<u8>,
}

/// A composed sheet (RGBA8).
#[derive(Clone, Debug)]
pub struct Sheet {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Columns of tiles.
    pub columns: u32,
    /// Rows of tiles.
    pub rows: u32,
    /// RGBA8 pixels.
    pub rgba: Vec<u8>,
}

/// The top-left pixel of tile `k` (row-major) on a sheet of `columns` columns of
/// `tile_w x tile_h` frames.
pub fn tile_origin(k: u32, columns: u32, tile_w: u32, tile_h: u32) -> (u32, u32) {
    let (col, row) = (k % columns, k / columns);
    (
        GAP + col * (tile_w + GAP),
        GAP + row * (tile_h + LABEL_HEIGHT + GAP),
    )
}

/// Lays `tiles` (each `tile_w x tile_h`) out in `columns` columns (rows as needed) on a
/// white sheet and writes each label under its tile.
pub fn compose(tiles: &[Tile], tile_w: u32, tile_h: u32, columns: u32) -> Result<Sheet> {
    let expected = tile_w as usize * tile_h as usize * 4;
    if tiles.is_empty() || columns == 0 || tile_w == 0 || tile_h == 0 {
        return Err(Error::invalid("contact sheet", "no tiles to lay out"));
    }
    if let Some(t) = tiles.iter().find(|t| t.rgba.len() != expected) {
        return Err(Error::invalid(
            "contact sheet",
            format!("tile '{}' is not {tile_w}x{tile_h} RGBA8", t.label),
        ));
    }
    let columns = columns.min(tiles.len() as u32);
    let rows = (tiles.len() as u32).div_ceil(columns);
    let width = GAP + columns * (tile_w + GAP);
    let height = GAP + rows * (tile_h + LABEL_HEIGHT + GAP);
    register_font()?;
    let mut rgb = vec![255u8; width as usize * height as usize * 3];
    for (k, tile) in tiles.iter().enumerate() {
        let (x0, y0) = tile_origin(k as u32, columns, tile_w, tile_h);
        for y in 0..tile_h {
            for x in 0..tile_w {
                let src = ((y * tile_w + x) * 4) as usize;
                let dst = (((y0 + y) * width + x0 + x) * 3) as usize;
                rgb[dst..dst + 3].copy_from_slice(&tile.rgba[src..src + 3]);
            }
        }
    }
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
        let style = (FAMILY, 15).into_font().color(&BLACK);
        for (k, tile) in tiles.iter().enumerate() {
            let (x0, y0) = tile_origin(k as u32, columns, tile_w, tile_h);
            root.draw(&Text::new(
                tile.label.clone(),
                (x0 as i32 + 2, (y0 + tile_h + 3) as i32),
                style.clone(),
            ))
            .map_err(|e| Error::invalid("contact sheet", e.to_string()))?;
        }
        root.present()
            .map_err(|e| Error::invalid("contact sheet", e.to_string()))?;
    }
    let rgba = rgb
        .chunks_exact(3)
        .flat_map(|p| [p[0], p[1], p[2], 255])
        .collect();
    Ok(Sheet {
        width,
        height,
        columns,
        rows,
        rgba,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_land_in_their_cells_with_labels_below() {
        let (w, h) = (40, 30);
        let tiles: Vec<Tile> = (0..5u8)
            .map(|k| Tile {
                label: format!("m{k}"),
                rgba: [10 * k, 200, 30, 255].repeat((w * h) as usize),
            })
            .collect();
        let sheet = compose(&tiles, w, h, 3).unwrap();
        assert_eq!((sheet.columns, sheet.rows), (3, 2));
        for k in 0..5 {
            let (x0, y0) = tile_origin(k, 3, w, h);
            let at = |x: u32, y: u32| {
                let i = ((y * sheet.width + x) * 4) as usize;
                [sheet.rgba[i], sheet.rgba[i + 1], sheet.rgba[i + 2]]
            };
            assert_eq!(at(x0 + w / 2, y0 + h / 2), [10 * k as u8, 200, 30]);
            // The label band holds dark text pixels.
            let dark = (y0 + h..y0 + h + LABEL_HEIGHT)
                .flat_map(|y| (x0..x0 + w).map(move |x| (x, y)))
                .filter(|&(x, y)| at(x, y)[0] < 128)
                .count();
            assert!(dark > 5, "tile {k}: {dark} text pixels");
        }
        assert!(compose(&tiles[..1], w + 1, h, 3).is_err());
    }
}
