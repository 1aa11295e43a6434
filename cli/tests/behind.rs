//! A miss shows what is behind it: in `scenes/materials.toml` the bricks cube (clamp
//! addressing, `exact`) has rays through its carved bottom edge that leave the decal
//! without meeting the relief. With the renderer's behind layer (on by default for a
//! scene of several objects) those pixels show the rocks floor: the behind layer's
//! G-buffer has the floor's material there, its trace hits, and the colour is the lit
//! stone (red above blue), where without the layer it is the sky (blue above red).
//! Validation (core + synchronization) on: zero messages, nothing left allocated.

#[path = "../../tests/common/mod.rs"]
mod common;

use common::{finish, validated_context};
use dispmap::renderer::Renderer;
use dispmap_cli::scene_file;

#[test]
fn the_floor_shows_under_the_cubes_carved_bottom_edge() {
    let ctx = validated_context();
    {
        let path = common::repo_root().join("scenes/materials.toml");
        let mut loaded = scene_file::load(&path).unwrap();
        let (w, h) = (192u32, 108u32);
        (loaded.settings.width, loaded.settings.height) = (w, h);
        let mut renderer =
            Renderer::with_assets(&ctx, &loaded.field, loaded.settings, &loaded.assets).unwrap();
        assert!(
            renderer.behind(),
            "a scene of several objects draws the behind layer"
        );
        // The objects' materials: the rocks floor (quad) and the bricks cube.
        let materials = renderer.object_materials();
        let floor = materials[0].unwrap().index();
        let cube = materials[1].unwrap().index();

        renderer.render().unwrap();
        let first = renderer.read_materials().unwrap();
        let hits = renderer.read_hits().unwrap();
        let behind_materials = renderer.read_behind_materials().unwrap().unwrap();
        let behind_hits = renderer.read_behind_hits().unwrap().unwrap();
        let with = renderer.read_color().unwrap();
        renderer.set_behind(false).unwrap();
        renderer.render().unwrap();
        assert_eq!(renderer.read_behind_hits().unwrap(), None);
        let without = renderer.read_color().unwrap();
        // The first layer is the same with and without.
        assert_eq!(renderer.read_hits().unwrap(), hits);

        let missed: Vec<usize> = (0..first.len())
            .filter(|&i| first[i] == Some(cube) && hits[i][2] == -1.0)
            .collect();
        let on_floor: Vec<usize> = missed
            .iter()
            .copied()
            .filter(|&i| behind_materials[i] == Some(floor))
            .collect();
        let rgb = |c: &[u8], i: usize| [c[4 * i], c[4 * i + 1], c[4 * i + 2]];
        eprintln!(
            "cube pixels {}, missed {}, floor behind {}",
            first.iter().filter(|m| **m == Some(cube)).count(),
            missed.len(),
            on_floor.len()
        );
        // The carved bottom edge: a strip of missed pixels with the floor behind them.
        assert!(on_floor.len() >= 20, "{} pixels", on_floor.len());
        for &i in &on_floor {
            let (x, y) = (i as u32 % w, i as u32 / w);
            // The floor's relief is traced there: a hit on the floor's map.
            let hit = behind_hits[i];
            assert!((0.0..=1.0).contains(&hit[2]), "({x}, {y}): behind hit {hit:?}");
            let (a, b) = (rgb(&without, i), rgb(&with, i));
            // Without the layer: the sky (its gradient is blue above red everywhere).
            assert!(a[2] > a[0], "({x}, {y}) without: {a:?} is not the sky");
            // With it: the lit stone of the floor (red above blue).
            assert!(b[0] > b[2], "({x}, {y}) with: {b:?} is not the floor");
        }
        // Pixels whose first trace hit have nothing in the behind layer, and keep their
        // colour.
        for i in 0..first.len() {
            if hits[i][2] != -1.0 {
                assert_eq!(behind_materials[i], None, "pixel {i}");
                assert_eq!(behind_hits[i][2], -1.0, "pixel {i}");
            }
            if !missed.contains(&i) && first[i].is_some() && hits[i][2] >= 0.0 {
                assert_eq!(rgb(&with, i), rgb(&without, i), "pixel {i}");
            }
        }
    }
    finish(ctx);
}
