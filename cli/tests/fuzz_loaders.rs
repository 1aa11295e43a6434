//! Property tests of the input loaders over random and mutated bytes (issue 7), a bounded
//! number of cases each so they run in CI (`PROPTEST_CASES` raises the count for a longer
//! local run). Every loader in [`LOADERS`] must, for any bytes, return either a valid
//! value or an error whose text names the input, and never panic. To fuzz another loader,
//! add a row to [`LOADERS`] and its seed files to [`seeds`].

use dispmap::heightfield::{Convention, HeightField, Texels};
use dispmap_cli::scene_file::SceneFile;
use image::{DynamicImage, ImageFormat};
use proptest::prelude::*;
use std::io::Cursor;
use std::path::Path;

/// The label every loader is given; its errors must contain it.
const LABEL: &str = "fuzzed-input.bin";

/// A loader under test: its name, and a function that loads bytes labelled [`LABEL`] and
/// checks the value's invariants (`Err`: the loader's error text).
type Loader = (&'static str, fn(&[u8]) -> Result<(), String>);

const LOADERS: &[Loader] = &[
    ("height map (height)", |b| height_map(b, Convention::Height)),
    ("height map (depth)", |b| height_map(b, Convention::Depth)),
    ("scene file", scene),
];

/// Parses a scene file (bytes as UTF-8, invalid sequences replaced) and resolves its
/// settings without reading any file: a scene that parses gives settings that pass
/// validation, or an error naming the file.
fn scene(bytes: &[u8]) -> Result<(), String> {
    let text = String::from_utf8_lossy(bytes);
    let path = Path::new(LABEL);
    let file = SceneFile::parse(&text, path).map_err(|e| e.to_string())?;
    let settings = file.settings(path).map_err(|e| e.to_string())?;
    if let Err(e) = settings.validate() {
        panic!("settings() accepted a scene whose settings do not validate: {e}");
    }
    Ok(())
}

/// Decodes a height map and checks what every loaded map guarantees: a non-empty size,
/// one texel per pixel, every height finite and in [0, 1].
fn height_map(bytes: &[u8], convention: Convention) -> Result<(), String> {
    let field = HeightField::decode(bytes, convention, LABEL).map_err(|e| e.to_string())?;
    let (w, h) = (field.width(), field.height());
    assert!(w > 0 && h > 0, "empty map loaded");
    let n = w as usize * h as usize;
    let len = match field.texels() {
        Texels::R8(v) => v.len(),
        Texels::R16(v) => v.len(),
        Texels::R32F(v) => v.len(),
    };
    assert_eq!(len, n, "texel count");
    for j in 0..h {
        for i in 0..w {
            let t = field.texel(i, j);
            assert!(
                t.is_finite() && (0.0..=1.0).contains(&t),
                "texel ({i}, {j}) = {t}"
            );
        }
    }
    Ok(())
}

fn encode(image: DynamicImage, format: ImageFormat) -> Vec<u8> {
    let mut bytes = Vec::new();
    image
        .write_to(&mut Cursor::new(&mut bytes), format)
        .unwrap();
    bytes
}

/// Small valid files of every kind the loaders read, to mutate.
fn seeds() -> Vec<Vec<u8>> {
    let gray8 = image::GrayImage::from_fn(23, 17, |x, y| image::Luma([(x * 11 + y * 7) as u8]));
    let gray16 = image::ImageBuffer::<image::Luma<u16>, _>::from_fn(9, 31, |x, y| {
        image::Luma([(x * 3001 + y * 17) as u16])
    });
    let rgb8 = image::RgbImage::from_fn(16, 16, |x, y| image::Rgb([x as u8 * 9, y as u8 * 13, 77]));
    let float = image::Rgb32FImage::from_fn(7, 5, |x, y| {
        let v = (x + 7 * y) as f32 / 35.0;
        image::Rgb([v, v, v])
    });
    vec![
        encode(DynamicImage::ImageLuma8(gray8.clone()), ImageFormat::Png),
        encode(DynamicImage::ImageLuma16(gray16), ImageFormat::Png),
        encode(DynamicImage::ImageRgb8(rgb8), ImageFormat::Png),
        encode(DynamicImage::ImageLuma8(gray8), ImageFormat::Jpeg),
        encode(DynamicImage::ImageRgb32F(float), ImageFormat::OpenExr),
    ]
    .into_iter()
    .chain(scene_seeds())
    .collect()
}

/// The example scenes in `scenes/`.
fn scene_seeds() -> Vec<Vec<u8>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("scenes");
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    assert!(
        !files.is_empty(),
        "no example scenes to seed the scene fuzzer"
    );
    files
        .into_iter()
        .map(|p| std::fs::read(p).unwrap())
        .collect()
}

/// Runs every loader on `bytes`: a valid value (checked) or an error naming the input.
fn check_all(bytes: &[u8]) -> Result<(), TestCaseError> {
    for (name, load) in LOADERS {
        if let Err(message) = load(bytes) {
            prop_assert!(
                message.contains(LABEL),
                "{name}: error does not name the input: {message}"
            );
        }
    }
    Ok(())
}

/// A seed, a few byte overwrites at random positions and an optional truncation.
fn mutated() -> impl Strategy<Value = Vec<u8>> {
    let n = seeds().len();
    (
        0..n,
        prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..8),
        prop::option::of(any::<prop::sample::Index>()),
    )
        .prop_map(|(seed, flips, cut)| {
            let mut bytes = seeds().swap_remove(seed);
            for (at, value) in flips {
                let i = at.index(bytes.len());
                bytes[i] = value;
            }
            if let Some(cut) = cut {
                bytes.truncate(cut.index(bytes.len()));
            }
            bytes
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// Arbitrary bytes, with and without a valid signature in front.
    #[test]
    fn random_bytes(prefix in 0usize..4, body in prop::collection::vec(any::<u8>(), 0..512)) {
        let signatures: [&[u8]; 4] = [b"", b"\x89PNG\r\n\x1a\n", b"\xff\xd8\xff\xe0", b"\x76\x2f\x31\x01"];
        let bytes = [signatures[prefix], &body].concat();
        check_all(&bytes)?;
    }

    /// Valid files with bytes overwritten and cut short.
    #[test]
    fn mutated_files(bytes in mutated()) {
        check_all(&bytes)?;
    }

    /// Scene files with random numbers (NaN, infinities, negatives, huge values among
    /// them) in every numeric key: accepted exactly when the settings validate, and the
    /// error names the file otherwise.
    #[test]
    fn scene_numbers_are_checked(
        values in prop::collection::vec(
            prop_oneof![
                2 => (-100.0f64..200.0).prop_map(|v| format!("{v}")),
                1 => prop::sample::select(vec!["nan", "inf", "-inf", "0", "-1", "1e30", "4294967296", "0.0"]).prop_map(str::to_owned),
            ],
            11,
        ),
    ) {
        let keys = [
            ("camera", "elevation"), ("camera", "azimuth"), ("camera", "fov"), ("camera", "height"),
            ("light", "elevation"), ("light", "azimuth"), ("light", "intensity"),
            ("heightmap", "depth_scale"), ("method", "steps"), ("method", "eps"), ("method", "lod_threshold"),
        ];
        let mut text = String::new();
        for table in ["camera", "light", "heightmap", "method"] {
            text.push_str(&format!("[{table}]\n"));
            for ((t, key), value) in keys.iter().zip(&values) {
                if *t == table {
                    text.push_str(&format!("{key} = {value}\n"));
                }
            }
        }
        if let Err(message) = scene(text.as_bytes()) {
            prop_assert!(message.contains(LABEL), "error does not name the file: {message}");
        }
    }

    /// Random valid 8- and 16-bit grey PNGs load exactly (height convention: the values;
    /// depth convention: their complement).
    #[test]
    fn valid_grey_maps_round_trip(
        w in 1u32..40,
        h in 1u32..40,
        sixteen in any::<bool>(),
        seed in any::<u64>(),
    ) {
        let value = |i: u32, j: u32| seed.wrapping_mul(u64::from(i * 131 + j * 7 + 1)).rotate_left(17);
        let (image, expect): (DynamicImage, Vec<f32>) = if sixteen {
            let img = image::ImageBuffer::<image::Luma<u16>, _>::from_fn(w, h, |i, j| image::Luma([value(i, j) as u16]));
            let expect = img.pixels().map(|p| f32::from(p.0[0]) / 65535.0).collect();
            (DynamicImage::ImageLuma16(img), expect)
        } else {
            let img = image::GrayImage::from_fn(w, h, |i, j| image::Luma([value(i, j) as u8]));
            let expect = img.pixels().map(|p| f32::from(p.0[0]) / 255.0).collect();
            (DynamicImage::ImageLuma8(img), expect)
        };
        let bytes = encode(image, ImageFormat::Png);
        for convention in [Convention::Height, Convention::Depth] {
            let field = HeightField::decode(&bytes, convention, LABEL).unwrap();
            prop_assert_eq!((field.width(), field.height()), (w, h));
            for j in 0..h {
                for i in 0..w {
                    let want = expect[(j * w + i) as usize];
                    let want = if convention == Convention::Depth { 1.0 - want } else { want };
                    prop_assert!((field.texel(i, j) - want).abs() <= 1e-6);
                }
            }
        }
    }

    /// Float heights: accepted exactly when every value is finite and in [0, 1], and the
    /// error names the input otherwise.
    #[test]
    fn float_heights_are_range_checked(
        values in prop::collection::vec(
            prop_oneof![4 => 0.0f32..=1.0, 1 => any::<f32>()],
            1..64,
        ),
    ) {
        let n = values.len() as u32;
        let valid = values.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v));
        match HeightField::from_heights(n, 1, values, LABEL) {
            Ok(field) => {
                prop_assert!(valid);
                prop_assert_eq!(field.width(), n);
            }
            Err(e) => {
                prop_assert!(!valid, "{}", e);
                prop_assert!(e.to_string().contains(LABEL));
            }
        }
    }
}

/// glTF files whose node graph is not a forest, or whose buffers point outside their
/// folder, are refused naming the file and the node or buffer (they used to make the
/// loader allocate until the process aborted, or read any file).
#[test]
fn gltf_cycles_shared_nodes_and_outside_buffers_are_refused() {
    let dir = std::env::temp_dir().join(format!("dispmap-gltf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cases = [
        (
            "self.gltf",
            r#"{"asset":{"version":"2.0"},"scenes":[{"nodes":[0]}],"nodes":[{"children":[0]}]}"#,
            "node 0 is reached twice",
        ),
        (
            "pair.gltf",
            r#"{"asset":{"version":"2.0"},"scenes":[{"nodes":[0]}],"nodes":[{"children":[1]},{"children":[0]}]}"#,
            "reached twice",
        ),
        (
            "diamond.gltf",
            r#"{"asset":{"version":"2.0"},"scenes":[{"nodes":[0]}],"nodes":[{"children":[1,2]},{"children":[3]},{"children":[3]},{}]}"#,
            "node 3 is reached twice",
        ),
        (
            "outside.gltf",
            r#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":4,"uri":"../secret.bin"}],"scenes":[{"nodes":[]}]}"#,
            "points outside the file's folder",
        ),
        (
            "absolute.gltf",
            r#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":4,"uri":"/etc/hostname"}],"scenes":[{"nodes":[]}]}"#,
            "points outside the file's folder",
        ),
    ];
    for (name, json, expected) in cases {
        let path = dir.join(name);
        std::fs::write(&path, json).unwrap();
        let err = dispmap_cli::mesh_file::load(&path)
            .err()
            .unwrap_or_else(|| panic!("{name} loaded"))
            .to_string();
        assert!(
            err.contains(name) && err.contains(expected),
            "{name}: {err}"
        );
    }
}
