//! The smallest use of the library: render a height map with one method, measure it
//! against the exact reference and write the picture.
//!
//! `cargo run --example render -- path/to/map.png depth out.png`

use dispmap::{
    Context, ContextOptions, HeightField, Method, MethodParams, RenderSettings, Renderer, Scene,
};
use dispmap_cli::measure::Measure as _;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let (map, convention, out) = match (args.next(), args.next(), args.next()) {
        (Some(m), Some(c), Some(o)) => (m, c, o),
        _ => anyhow::bail!("usage: render MAP height|depth OUT.png"),
    };
    let field = HeightField::load(map.as_ref(), convention.parse()?)?;
    let ctx = std::sync::Arc::new(Context::headless(&ContextOptions::default())?);
    let settings = RenderSettings {
        shadows: Default::default(),
        width: 320,
        height: 180,
        method: Method::Relief,
        params: MethodParams::default(),
        scene: Scene::default(),
    };
    let mut renderer = Renderer::new(&ctx, &field, settings)?;
    let reference = dispmap_cli::reference::Reference::new(&field, settings.scene.addressing());
    let frame_ref = renderer.reference(&reference)?;
    let m = renderer.measure(&frame_ref, 3)?;
    println!("{:?}\n{:?}", m.timings_ms, m.error);
    dispmap_cli::output::write_png(out.as_ref(), settings.width, settings.height, &m.color)?;
    Ok(())
}
