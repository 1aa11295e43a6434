//! Scene files: a small TOML description of everything a frame needs (height map,
//! material maps, macro geometry, camera, light, method, frame size), rendered with
//! `dispmap render --scene FILE`.
//!
//! Every key is optional and has a default, so a scene states only what differs. An
//! unknown key (a typo) is an error that names the key and the file. Paths are relative
//! to the scene file's folder. The keys and their defaults:
//!
//! ```toml
//! geometry = "plane"      # plane | quad | cube | sphere | torus | mesh
//! mesh = "model.obj"      # OBJ or glTF (.gltf, .glb) of geometry = "mesh" (only there)
//! size = [640, 360]       # frame width and height in pixels
//!
//! [heightmap]
//! bundled = "rocks"       # rocks | bricks | mountains (the default when no path)
//! path = "height.png"     # a PNG (8/16-bit), JPEG or OpenEXR file instead
//! convention = "height"   # of `path`: height (white = high) | depth (white = deep)
//! depth_scale = 0.1       # displacement depth in tiles (uv units)
//! addressing = "repeat"   # repeat | clamp; default: the geometry's (clamp for quad, cube)
//!
//! [material]
//! albedo = "albedo.png"   # sRGB colour map (default: none, a stone colour)
//! normal_map = "n.png"    # tangent-space normal map (default: none, from the height map)
//! normal_map_green = "up" # up (OpenGL convention) | down (DirectX convention)
//!
//! [camera]
//! elevation = 30.0        # degrees above the plane (orbit elevation for objects)
//! azimuth = 0.0           # degrees about the vertical axis
//! fov = 45.0              # vertical field of view, degrees
//! height = 0.25           # eye height above the tiled plane, tiles (plane only)
//! distance = 3.0          # orbit distance, world units (not the plane; default: framed)
//!
//! [light]
//! elevation = 35.0        # degrees
//! azimuth = 60.0          # degrees
//! intensity = 1.0
//!
//! [method]
//! name = "relief"         # bump | linear | relief | pom | secant | dig | dig-guarded | pyramid | exact
//! steps = 64              # default: the method's (secant 15, others 64)
//! min_steps = 8           # pom's n_min
//! refine_steps = 5        # binary-search steps (relief, dig)
//! segments = 1            # secant's segments
//! block = [4, 4]          # dig's block size in pixels
//! eps = 0.015625          # dig's interval widening (default: 1 / steps)
//! max_level = 0           # pyramid's coarsest level, or "auto"
//!
//! [[object]]              # a scene of several objects (crate::scene_objects), each:
//! geometry = "cube"       # required: plane | quad | cube | sphere | torus | mesh
//! position = [0, 0, 0]    # world units; scale = 1.0; rotation = [x, y, z] degrees
//! [object.heightmap]      # as [heightmap]; absent: the object is drawn flat
//! [object.method]         # as [method]; absent: the scene's [method]
//! [object.material]       # as [material]
//! ```

use crate::bundled;
use dispmap::error::{Error, Result};
use dispmap::heightfield::{Addressing, Convention, HeightField};
use dispmap::material::{self, MaterialImages};
use dispmap::method::{MaxLevel, Method, MethodParams};
use dispmap::passes::shadow::{ShadowMode, ShadowSettings};
use dispmap::renderer::{RenderSettings, SceneAssets};
use dispmap::scene::{Camera, Geometry, Light, Scene, reduce_degrees};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The largest scene file read (1 MiB; a scene is a few hundred bytes).
pub const MAX_SCENE_BYTES: u64 = 1 << 20;

/// Why `two_sided` is refused on a geometry other than `mesh`.
pub const TWO_SIDED_ONLY_MESH: &str = "`two_sided` is only read with geometry = \"mesh\" (the \
     generated cube, sphere and torus are closed: their inside is never seen)";

/// Default frame size of a scene file.
pub const DEFAULT_SIZE: [u32; 2] = [640, 360];

/// A parsed scene file (every key optional; [`SceneFile::resolve`] fills the defaults).
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneFile {
    /// `plane`, `quad`, `cube`, `sphere`, `torus` or `mesh`.
    pub geometry: Option<String>,
    /// The OBJ file of `geometry = "mesh"`.
    pub mesh: Option<PathBuf>,
    /// Draw the mesh of `geometry = "mesh"` two-sided (its inside displaced as seen
    /// from there; default: the glTF material's `doubleSided`, else off).
    pub two_sided: Option<bool>,
    /// Frame width and height.
    #[serde(deserialize_with = "pair")]
    pub size: Option<[u32; 2]>,
    /// `[heightmap]`.
    pub heightmap: HeightmapKeys,
    /// `[material]`.
    pub material: MaterialKeys,
    /// `[camera]`.
    pub camera: CameraKeys,
    /// `[light]`.
    pub light: LightKeys,
    /// `[method]`.
    pub method: MethodKeys,
    /// `[[object]]`: a scene of several objects (none: the one geometry of the keys
    /// above). See [`ObjectKeys`].
    pub object: Vec<ObjectKeys>,
}

/// One `[[object]]` of a scene of several objects: its geometry, placement and, when it
/// is displaced, its height map, method and material maps.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ObjectKeys {
    /// `plane`, `quad`, `cube`, `sphere`, `torus` or `mesh` (default: `cube`).
    pub geometry: Option<String>,
    /// The OBJ or glTF file of `geometry = "mesh"`.
    pub mesh: Option<PathBuf>,
    /// Draw the mesh two-sided, as the scene's `two_sided`.
    pub two_sided: Option<bool>,
    /// `[x, y, z]`, world units (not for the plane).
    #[serde(deserialize_with = "triple")]
    pub position: Option<[f32; 3]>,
    /// Uniform scale (not for the plane).
    pub scale: Option<f32>,
    /// `[x, y, z]`: degrees about the x, then y, then z axis (not for the plane).
    #[serde(deserialize_with = "triple")]
    pub rotation: Option<[f32; 3]>,
    /// `[object.heightmap]`; absent: the object is drawn flat (not displaced).
    pub heightmap: Option<HeightmapKeys>,
    /// `[object.method]`; absent: the scene's `[method]`.
    pub method: Option<MethodKeys>,
    /// `[object.material]` (albedo, normal map).
    pub material: Option<MaterialKeys>,
}

/// `[heightmap]`.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HeightmapKeys {
    /// A bundled map's name.
    pub bundled: Option<String>,
    /// A map file.
    pub path: Option<PathBuf>,
    /// How `path` encodes heights.
    pub convention: Option<Convention>,
    /// Displacement depth.
    pub depth_scale: Option<f32>,
    /// Addressing.
    pub addressing: Option<Addressing>,
}

/// Refuses an empty file name (`mesh = ""`), which names no file: `key` and the scene
/// file `path` name it in the error.
pub fn check_file_key(key: &str, value: Option<&Path>, path: &Path) -> Result<()> {
    if value.is_some_and(|v| v.as_os_str().is_empty()) {
        return Err(Error::invalid(
            format!("{key} in {}", path.display()),
            "is empty: it names no file",
        ));
    }
    Ok(())
}

impl HeightmapKeys {
    /// Checks the keys together (`key` names the table in errors: `heightmap`).
    pub fn check(&self, key: &str, path: &Path) -> Result<()> {
        check_file_key(&format!("{key}.path"), self.path.as_deref(), path)?;
        if self.bundled.is_some() && self.path.is_some() {
            return Err(Error::invalid(
                format!("{key} in {}", path.display()),
                "give either `bundled` or `path`, not both",
            ));
        }
        if self.bundled.is_some() && self.convention.is_some() {
            return Err(Error::invalid(
                format!("{key}.convention in {}", path.display()),
                "a bundled map has its own convention; `convention` is for `path`",
            ));
        }
        if self.path.is_some() && self.convention.is_none() {
            return Err(Error::invalid(
                format!("{key}.convention in {}", path.display()),
                "a map given by `path` needs `convention = \"height\"` (white = high) or \
                 `\"depth\"` (white = deep), as --convention does on the command line",
            ));
        }
        Ok(())
    }

    /// Where the map comes from (a path relative to `path`'s folder; `key` names the
    /// table in errors); nothing is read.
    pub fn source(&self, key: &str, path: &Path) -> MapSource {
        let dir = path.parent().unwrap_or(Path::new("."));
        match &self.path {
            Some(p) => MapSource::File {
                path: dir.join(p),
                convention: self.convention.unwrap_or(Convention::Height),
            },
            None => MapSource::Bundled {
                name: self.bundled.clone().unwrap_or_else(|| "rocks".into()),
                option: format!("{key}.bundled in {}", path.display()),
            },
        }
    }
}

impl MethodKeys {
    /// The method (default `relief`) and its parameters with every default filled in
    /// (`path` names the file in errors).
    pub fn resolve(&self, path: &Path) -> Result<(Method, MethodParams)> {
        let m = self;
        let method = m.name.unwrap_or(Method::Relief);
        let defaults = MethodParams::for_method(method);
        let max_level = match &m.max_level {
            None => defaults.max_level,
            Some(MaxLevelKey::Level(l)) => MaxLevel::Fixed(*l),
            Some(MaxLevelKey::Name(s)) => s.parse().map_err(|e| in_file(path, e))?,
        };
        Ok((
            method,
            MethodParams {
                steps: m.steps.unwrap_or(defaults.steps),
                min_steps: m.min_steps.unwrap_or(defaults.min_steps),
                refine_steps: m.refine_steps.unwrap_or(defaults.refine_steps),
                segments: m.segments.unwrap_or(defaults.segments),
                block: m.block.unwrap_or(defaults.block),
                eps: m.eps.or(defaults.eps),
                max_level,
                lod_threshold: m.lod_threshold.or(defaults.lod_threshold),
            },
        ))
    }
}

/// Which way a normal map's green channel points.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GreenAxis {
    /// Up the image (OpenGL convention).
    Up,
    /// Down the image (DirectX convention).
    Down,
}

/// `[material]`.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MaterialKeys {
    /// Albedo map.
    pub albedo: Option<PathBuf>,
    /// Normal map.
    pub normal_map: Option<PathBuf>,
    /// Its green axis.
    pub normal_map_green: Option<GreenAxis>,
}

impl MaterialKeys {
    /// Checks the file names (`key` names the table in errors: `material`).
    pub fn check(&self, key: &str, path: &Path) -> Result<()> {
        check_file_key(&format!("{key}.albedo"), self.albedo.as_deref(), path)?;
        check_file_key(
            &format!("{key}.normal_map"),
            self.normal_map.as_deref(),
            path,
        )
    }
}

/// `[camera]`.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraKeys {
    /// Elevation, degrees.
    pub elevation: Option<f32>,
    /// Azimuth, degrees.
    pub azimuth: Option<f64>,
    /// Vertical field of view, degrees.
    pub fov: Option<f32>,
    /// Eye height (plane).
    pub height: Option<f32>,
    /// Orbit distance of the quad, a mesh or a scene of several objects (world units;
    /// default: the distance that frames them; the tiled plane's follows from `height`).
    pub distance: Option<f32>,
}

/// `[light]`.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LightKeys {
    /// Elevation, degrees.
    pub elevation: Option<f32>,
    /// Azimuth, degrees.
    pub azimuth: Option<f64>,
    /// Intensity.
    pub intensity: Option<f32>,
    /// Self-shadowing: `off` (default), `hard` or `soft` (`--shadows`).
    pub shadows: Option<ShadowMode>,
    /// Soft shadows: height samples along the light ray (`--shadow-samples`, default 8).
    pub shadow_samples: Option<u32>,
}

/// A level or `"auto"`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum MaxLevelKey {
    /// A fixed level.
    Level(u32),
    /// `"auto"`.
    Name(String),
}

/// `[method]`.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MethodKeys {
    /// The method (CLI name).
    pub name: Option<Method>,
    /// Steps.
    pub steps: Option<u32>,
    /// pom's n_min.
    pub min_steps: Option<u32>,
    /// Binary-search steps.
    pub refine_steps: Option<u32>,
    /// secant's segments.
    pub segments: Option<u32>,
    /// dig's block.
    #[serde(deserialize_with = "pair")]
    pub block: Option<[u32; 2]>,
    /// dig's eps.
    pub eps: Option<f32>,
    /// pyramid's max level.
    pub max_level: Option<MaxLevelKey>,
    /// Level of detail: the mip level past which the pixel takes bump mapping
    /// (`--lod-threshold`; default: no LOD).
    pub lod_threshold: Option<f32>,
}

/// A scene file resolved: settings with every default filled, the loaded height map and
/// what else the scene uses.
pub struct LoadedScene {
    /// The scene file.
    pub path: PathBuf,
    /// What to render.
    pub settings: RenderSettings,
    /// The height map.
    pub field: HeightField,
    /// A loaded mesh and the material maps.
    pub assets: SceneAssets,
    /// The height map's name (a bundled name or the file's path).
    pub heightmap: String,
}

/// An `[x, y, z]` key: exactly three numbers.
fn triple<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> std::result::Result<Option<[f32; 3]>, D::Error> {
    let values = Vec::<f32>::deserialize(d)?;
    match values[..] {
        [x, y, z] => Ok(Some([x, y, z])),
        _ => Err(serde::de::Error::custom(format!(
            "expected [x, y, z] (three numbers), found {} number(s): {values:?}",
            values.len()
        ))),
    }
}

/// A `[width, height]` key: exactly two numbers (serde's fixed-size arrays would let
/// `[640, 360, 2]` through).
fn pair<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Option<[u32; 2]>, D::Error> {
    let values = Vec::<u32>::deserialize(d)?;
    match values[..] {
        [w, h] => Ok(Some([w, h])),
        _ => Err(serde::de::Error::custom(format!(
            "expected [width, height] (two numbers), found {} number(s): {values:?}",
            values.len()
        ))),
    }
}

/// Where a scene's height map comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum MapSource {
    /// A file, in its convention.
    File {
        /// The file (relative paths resolved against the scene's folder).
        path: PathBuf,
        /// How it encodes heights.
        convention: Convention,
    },
    /// A bundled map by name; `option` names the key in errors.
    Bundled {
        /// rocks, bricks or mountains.
        name: String,
        /// The key and file, for errors.
        option: String,
    },
}

impl MapSource {
    /// Loads the map.
    pub fn load(&self) -> Result<HeightField> {
        match self {
            MapSource::File { path, convention } => HeightField::load(path, *convention),
            MapSource::Bundled { name, option } => bundled::by_name(name, option),
        }
    }

    /// The map's name: the file's path or the bundled name.
    pub fn label(&self) -> String {
        match self {
            MapSource::File { path, .. } => path.display().to_string(),
            MapSource::Bundled { name, .. } => name.clone(),
        }
    }
}

/// Names the file in an error about one of its values.
pub fn in_file(path: &Path, e: Error) -> Error {
    match e {
        Error::InvalidInput { name, message } => {
            Error::invalid(format!("{} in {}", name, path.display()), message)
        }
        other => other,
    }
}

impl SceneFile {
    /// Whether the scene lists objects (`[[object]]`, see [`crate::scene_objects`]).
    pub fn has_objects(&self) -> bool {
        !self.object.is_empty()
    }

    /// Resolves the `[[object]]`s ([`crate::scene_objects::specs`]) only to check them.
    fn check_objects(&self, path: &Path) -> Result<()> {
        crate::scene_objects::specs(self, path).map(drop)
    }

    /// Parses TOML text; errors name `path` and, for an unknown key, the key.
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        toml::from_str(text).map_err(|e| {
            Error::invalid(
                format!("scene file {}", path.display()),
                e.to_string().trim_end().to_owned(),
            )
        })
    }

    /// Reads and parses `path` (a regular file of at most [`MAX_SCENE_BYTES`]).
    pub fn read(path: &Path) -> Result<Self> {
        let text = dispmap::input::read_to_string(path, MAX_SCENE_BYTES, "a scene file")?;
        Self::parse(&text, path)
    }

    /// The geometry (default: the tiled plane).
    pub fn geometry(&self) -> Result<Geometry> {
        self.geometry
            .as_deref()
            .map_or(Ok(Geometry::TiledPlane), str::parse)
    }

    /// The render settings with every default filled in (no file is read). `path` is
    /// only used in error messages.
    // `..Scene::default()`: scene fields a scene file has no key for keep their defaults.
    #[allow(clippy::needless_update)]
    pub fn settings(&self, path: &Path) -> Result<RenderSettings> {
        let geometry = self.geometry().map_err(|e| in_file(path, e))?;
        let c = Camera::default();
        let l = Light::default();
        let (method, params) = self.method.resolve(path)?;
        let [width, height] = self.size.unwrap_or(DEFAULT_SIZE);
        let settings = RenderSettings {
            width,
            height,
            method,
            params,
            scene: Scene {
                geometry,
                depth_scale: self
                    .heightmap
                    .depth_scale
                    .unwrap_or(Scene::default().depth_scale),
                camera: Camera {
                    elevation_deg: self.camera.elevation.unwrap_or(c.elevation_deg),
                    azimuth_deg: self.camera.azimuth.map_or(c.azimuth_deg, reduce_degrees),
                    fov_y_deg: self.camera.fov.unwrap_or(c.fov_y_deg),
                    height: self.camera.height.unwrap_or(c.height),
                    distance: self.camera.distance,
                },
                light: Light {
                    elevation_deg: self.light.elevation.unwrap_or(l.elevation_deg),
                    azimuth_deg: self.light.azimuth.map_or(l.azimuth_deg, reduce_degrees),
                    intensity: self.light.intensity.unwrap_or(l.intensity),
                },
                addressing: self.heightmap.addressing,
                ..Scene::default()
            },
            shadows: ShadowSettings {
                mode: self.light.shadows.unwrap_or_default(),
                samples: self
                    .light
                    .shadow_samples
                    .unwrap_or(ShadowSettings::default().samples),
            },
        };
        settings.validate().map_err(|e| in_file(path, e))?;
        if geometry == Geometry::Mesh && self.mesh.is_none() {
            return Err(Error::invalid(
                format!("mesh in {}", path.display()),
                "geometry = \"mesh\" needs the `mesh` key (an OBJ or glTF file)",
            ));
        }
        if geometry != Geometry::Mesh && self.mesh.is_some() {
            return Err(Error::invalid(
                format!("mesh in {}", path.display()),
                "`mesh` is only read with geometry = \"mesh\"",
            ));
        }
        if geometry != Geometry::Mesh && self.two_sided.is_some() {
            return Err(Error::invalid(
                format!("two_sided in {}", path.display()),
                TWO_SIDED_ONLY_MESH,
            ));
        }
        check_file_key("mesh", self.mesh.as_deref(), path)?;
        self.heightmap.check("heightmap", path)?;
        self.material.check("material", path)?;
        if !self.object.is_empty() {
            self.check_objects(path)?;
        }
        Ok(settings)
    }

    /// Where the scene's height map comes from (a path relative to `path`'s folder);
    /// nothing is read.
    pub fn heightmap_source(&self, path: &Path) -> MapSource {
        self.heightmap.source("heightmap", path)
    }

    /// Loads the scene's mesh (when `with_mesh`: a command line that overrides the
    /// geometry does not need it) and material maps (paths relative to `path`'s folder).
    pub fn assets(&self, path: &Path, with_mesh: bool) -> Result<SceneAssets> {
        let dir = path.parent().unwrap_or(Path::new("."));
        let mesh = match &self.mesh {
            Some(m) if with_mesh => {
                let mut mesh = crate::mesh_file::load(&dir.join(m))?;
                mesh.two_sided = self.two_sided.unwrap_or(mesh.two_sided);
                Some(mesh)
            }
            _ => None,
        };
        let green_up = self.material.normal_map_green.unwrap_or(GreenAxis::Up) == GreenAxis::Up;
        let material = MaterialImages {
            albedo: match &self.material.albedo {
                Some(p) => Some(material::load_albedo(&dir.join(p))?),
                None => None,
            },
            normal_map: match &self.material.normal_map {
                Some(p) => Some(material::load_normal_map(&dir.join(p), green_up)?),
                None => None,
            },
        };
        Ok(SceneAssets {
            mesh,
            material,
            objects: Vec::new(),
        })
    }

    /// Resolves the scene: fills the defaults and loads the height map, mesh and maps
    /// (paths relative to `path`'s folder).
    pub fn resolve(&self, path: &Path) -> Result<LoadedScene> {
        let settings = self.settings(path)?;
        let source = self.heightmap_source(path);
        let field = source.load()?;
        let assets = self.assets(path, true)?;
        Ok(LoadedScene {
            path: path.to_owned(),
            settings,
            field,
            assets,
            heightmap: source.label(),
        })
    }
}

/// Reads, parses and resolves a scene file.
pub fn load(path: &Path) -> Result<LoadedScene> {
    SceneFile::read(path)?.resolve(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_keys_name_the_key_and_the_file() {
        let path = Path::new("scenes/typo.toml");
        for (text, key) in [
            ("geometri = \"cube\"\n", "geometri"),
            ("[camera]\nelevaton = 3\n", "elevaton"),
            ("[method]\nname = \"relief\"\nstep = 3\n", "step"),
        ] {
            let err = SceneFile::parse(text, path).unwrap_err().to_string();
            assert!(
                err.contains(key) && err.contains("scenes/typo.toml"),
                "{err}"
            );
        }
    }

    #[test]
    fn missing_keys_take_their_defaults() {
        let path = Path::new("s.toml");
        let empty = SceneFile::parse("", path).unwrap().settings(path).unwrap();
        assert_eq!(empty.scene, Scene::default());
        assert_eq!(empty.method, Method::Relief);
        assert_eq!(empty.params, MethodParams::for_method(Method::Relief));
        assert_eq!([empty.width, empty.height], DEFAULT_SIZE);
        let some = SceneFile::parse(
            "geometry = \"cube\"\n[camera]\nazimuth = 40\n[method]\nname = \"secant\"\nmax_level = \"auto\"\n",
            path,
        )
        .unwrap()
        .settings(path)
        .unwrap();
        assert_eq!(some.scene.geometry, Geometry::Cube);
        assert_eq!(some.scene.camera.azimuth_deg, 40.0);
        assert_eq!(
            some.scene.camera.elevation_deg,
            Camera::default().elevation_deg
        );
        assert_eq!(some.params.steps, 15);
        assert_eq!(some.params.max_level, MaxLevel::Auto);
    }

    #[test]
    fn bad_values_name_the_file() {
        let path = Path::new("bad.toml");
        for (text, what) in [
            ("[camera]\nelevation = 0\n", "camera-elevation"),
            ("geometry = \"cone\"\n", "cone"),
            ("geometry = \"mesh\"\n", "mesh"),
            (
                "[heightmap]\nbundled = \"rocks\"\npath = \"x.png\"\n",
                "both",
            ),
            ("[method]\nname = \"fast\"\n", "fast"),
            ("[heightmap]\npath = \"x.png\"\n", "heightmap.convention"),
            ("size = [64, 36, 2]\n", "two numbers"),
            ("[method]\nblock = [4]\n", "two numbers"),
        ] {
            let err = SceneFile::parse(text, path)
                .and_then(|f| f.settings(path))
                .unwrap_err()
                .to_string();
            assert!(err.contains(what) && err.contains("bad.toml"), "{err}");
        }
    }
}
