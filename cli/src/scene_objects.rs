//! Scenes of several objects: a scene file's `[[object]]` array resolved (every default
//! filled, nothing read: [`specs`]) and loaded (height maps, meshes, material maps:
//! [`load`]) into what [`dispmap::renderer::Renderer::with_objects`] draws.
//!
//! Each object has its own `geometry` (required), placement (`position`, `scale`,
//! `rotation`; the tiled plane has none) and either an `[object.heightmap]` (its keys and
//! defaults as the scene's `[heightmap]`), with an optional `[object.method]` (default:
//! the scene's `[method]`) and `[object.material]`, or no height map: drawn flat. With
//! `[[object]]` the scene's own `geometry`, `mesh`, `[heightmap]` and `[material]` are
//! refused (they belong to an object); `size`, `[camera]`, `[light]` and `[method]` (the
//! objects' default) stay the scene's.

use crate::scene_file::{GreenAxis, MapSource, MaterialKeys, SceneFile};
use dispmap::embed::MaterialSettings;
use dispmap::error::{Error, Result};
use dispmap::material::{self, MaterialImages};
use dispmap::renderer::ObjectAssets;
use dispmap::scene::{Geometry, Placement, Scene};
use glam::Vec3;
use std::path::{Path, PathBuf};

/// One object of a scene, resolved (nothing read).
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectSpec {
    /// Its geometry.
    pub geometry: Geometry,
    /// Its placement.
    pub placement: Placement,
    /// The mesh file of `geometry = "mesh"` (relative to the scene's folder, joined).
    pub mesh: Option<PathBuf>,
    /// `two_sided` of `geometry = "mesh"` (`None`: the mesh file's own).
    pub two_sided: Option<bool>,
    /// Its displacement; `None`: flat.
    pub material: Option<MaterialSpec>,
}

/// The displacement of one object, resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialSpec {
    /// Where its height map comes from.
    pub source: MapSource,
    /// Method, parameters, depth scale, addressing.
    pub settings: MaterialSettings,
    /// Its albedo and normal map keys.
    pub maps: MaterialKeys,
}

/// Names the object and the file in an error about one of its values.
fn in_object(path: &Path, index: usize, e: Error) -> Error {
    match e {
        Error::InvalidInput { name, message } => Error::invalid(
            format!("object {} {name} in {}", index + 1, path.display()),
            message,
        ),
        other => other,
    }
}

/// Resolves `file`'s objects (`path` is the scene file, for errors and relative paths).
/// Errors name the object (1-based), the key and the file.
pub fn specs(file: &SceneFile, path: &Path) -> Result<Vec<ObjectSpec>> {
    let refuse = |key: &str, given: bool| -> Result<()> {
        if given {
            return Err(Error::invalid(
                format!("{key} in {}", path.display()),
                "a scene with [[object]] gives it per object",
            ));
        }
        Ok(())
    };
    refuse("geometry", file.geometry.is_some())?;
    refuse("mesh", file.mesh.is_some())?;
    refuse("two_sided", file.two_sided.is_some())?;
    refuse("heightmap", file.heightmap != Default::default())?;
    refuse("material", file.material != Default::default())?;
    if file.object.len() > dispmap::renderer::MAX_OBJECTS {
        return Err(Error::invalid(
            format!("object in {}", path.display()),
            format!(
                "{} objects: a scene takes at most {}",
                file.object.len(),
                dispmap::renderer::MAX_OBJECTS
            ),
        ));
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut out = Vec::with_capacity(file.object.len());
    for (i, o) in file.object.iter().enumerate() {
        let err = |e: Error| in_object(path, i, e);
        let geometry: Geometry = o
            .geometry
            .as_deref()
            .ok_or_else(|| {
                Error::invalid(
                    "geometry",
                    "every object needs one: plane, quad, cube, sphere, torus or mesh",
                )
            })
            .and_then(str::parse)
            .map_err(err)?;
        match (geometry, &o.mesh) {
            (Geometry::Mesh, None) => {
                return Err(err(Error::invalid(
                    "mesh",
                    "geometry = \"mesh\" needs the `mesh` key (an OBJ or glTF file)",
                )));
            }
            (g, Some(_)) if g != Geometry::Mesh => {
                return Err(err(Error::invalid(
                    "mesh",
                    "`mesh` is only read with geometry = \"mesh\"",
                )));
            }
            _ => {}
        }
        if geometry != Geometry::Mesh && o.two_sided.is_some() {
            return Err(err(Error::invalid(
                "two_sided",
                crate::scene_file::TWO_SIDED_ONLY_MESH,
            )));
        }
        if o.mesh.as_ref().is_some_and(|m| m.as_os_str().is_empty()) {
            return Err(err(Error::invalid("mesh", "is empty: it names no file")));
        }
        let placed = o.position.is_some() || o.scale.is_some() || o.rotation.is_some();
        if geometry == Geometry::TiledPlane && placed {
            return Err(err(Error::invalid(
                "position",
                "the tiled plane has no position, scale or rotation",
            )));
        }
        let placement = Placement {
            position: Vec3::from(o.position.unwrap_or([0.0; 3])),
            scale: o.scale.unwrap_or(1.0),
            rotation_deg: Vec3::from(o.rotation.unwrap_or([0.0; 3])),
        };
        placement.validate().map_err(err)?;
        let material = match &o.heightmap {
            None => {
                if o.method.is_some() || o.material.is_some() {
                    return Err(err(Error::invalid(
                        "heightmap",
                        "[object.method] and [object.material] need [object.heightmap] \
                         (an object without one is drawn flat)",
                    )));
                }
                None
            }
            Some(h) => {
                let key = format!("object {} heightmap", i + 1);
                h.check(&key, path)?;
                if let Some(m) = &o.material {
                    m.check(&format!("object {} material", i + 1), path)?;
                }
                let (method, params) = o.method.as_ref().unwrap_or(&file.method).resolve(path)?;
                // The command line's checks of a method's values, the same code.
                method.check_params(&params).map_err(err)?;
                let depth_scale = h.depth_scale.unwrap_or(Scene::default().depth_scale);
                // The scene's own checks of a depth scale (its range).
                Scene {
                    depth_scale,
                    ..Scene::default()
                }
                .validate()
                .map_err(err)?;
                Some(MaterialSpec {
                    source: h.source(&key, path),
                    settings: MaterialSettings {
                        method,
                        params,
                        depth_scale,
                        addressing: h.addressing.unwrap_or_else(|| geometry.addressing()),
                    },
                    maps: o.material.clone().unwrap_or_default(),
                })
            }
        };
        out.push(ObjectSpec {
            geometry,
            placement,
            mesh: o.mesh.as_ref().map(|m| dir.join(m)),
            two_sided: o.two_sided,
            material,
        });
    }
    if !out.iter().any(|o| o.material.is_some()) {
        return Err(Error::invalid(
            format!("object in {}", path.display()),
            "no object has a [object.heightmap]: at least one must be displaced",
        ));
    }
    Ok(out)
}

/// Refuses an object whose method needs more loop iterations per invocation than the
/// device runs (`loop_limit`, [`dispmap::Method::check_loop_limit`]), naming the object
/// and the scene file `path`, before anything is uploaded.
pub fn check_loop_limits(specs: &[ObjectSpec], path: &Path, loop_limit: Option<u32>) -> Result<()> {
    let Some(limit) = loop_limit else {
        return Ok(());
    };
    for (i, spec) in specs.iter().enumerate() {
        if let Some(m) = &spec.material {
            m.settings
                .method
                .check_loop_limit(&m.settings.params, limit)
                .map_err(|e| in_object(path, i, e))?;
        }
    }
    Ok(())
}

/// An albedo or normal map as loaded: its file and, for a normal map, whether its green
/// is flipped (`None` for an albedo). Objects naming the same map share one copy.
type ImageKey = (PathBuf, Option<bool>);

/// The albedo and normal map keys of `keys` (paths relative to `dir`).
fn image_keys(keys: &MaterialKeys, dir: &Path) -> [Option<ImageKey>; 2] {
    let green_up = keys.normal_map_green.unwrap_or(GreenAxis::Up) == GreenAxis::Up;
    [
        keys.albedo.as_ref().map(|p| (dir.join(p), None)),
        keys.normal_map
            .as_ref()
            .map(|p| (dir.join(p), Some(green_up))),
    ]
}

/// The albedo and normal maps of `materials` (each one material's keys, paths relative
/// to `dir`) for the memory estimate, from their files' headers (nothing is decoded):
/// each file's texels counted once, as [`load`] shares them, and each material's GPU
/// copies.
pub fn measure_images<'a>(
    materials: impl IntoIterator<Item = &'a MaterialKeys>,
    dir: &Path,
) -> Result<crate::memory::MaterialMaps> {
    let mut seen = std::collections::HashSet::new();
    let mut out = crate::memory::MaterialMaps::default();
    for keys in materials {
        for key in image_keys(keys, dir).into_iter().flatten() {
            let header = dispmap::HeightField::probe(&key.0)?;
            let first = seen.insert(key);
            out.add(&header, first);
        }
    }
    Ok(out)
}

/// Loads the albedo and normal map of `keys` (paths relative to `dir`); a map already in
/// `loaded` is shared (its texels are not read or held twice).
fn load_images(
    keys: &MaterialKeys,
    dir: &Path,
    loaded: &mut std::collections::HashMap<ImageKey, material::RgbaMap>,
) -> Result<MaterialImages> {
    let [albedo, normal_map] = image_keys(keys, dir).map(|key| {
        let Some(key) = key else {
            return Ok(None);
        };
        if let Some(map) = loaded.get(&key) {
            return Ok(Some(map.clone()));
        }
        let map = match key.1 {
            None => material::load_albedo(&key.0)?,
            Some(green_up) => material::load_normal_map(&key.0, green_up)?,
        };
        loaded.insert(key, map.clone());
        Ok(Some(map))
    });
    Ok(MaterialImages {
        albedo: albedo?,
        normal_map: normal_map?,
    })
}

/// Loads every object's height map, mesh and material maps (`path`: the scene file),
/// in the order of `specs`; objects naming the same albedo or normal map share it.
pub fn load(specs: &[ObjectSpec], path: &Path) -> Result<Vec<ObjectAssets>> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut images = std::collections::HashMap::new();
    specs
        .iter()
        .map(|spec| {
            let mesh = match &spec.mesh {
                Some(m) => {
                    let mut mesh = crate::mesh_file::load(m)?;
                    mesh.two_sided = spec.two_sided.unwrap_or(mesh.two_sided);
                    Some(mesh)
                }
                None => None,
            };
            let material = match &spec.material {
                Some(m) => Some((
                    m.source.load()?,
                    m.settings,
                    load_images(&m.maps, dir, &mut images)?,
                )),
                None => None,
            };
            Ok(ObjectAssets {
                geometry: spec.geometry,
                placement: spec.placement,
                mesh,
                material,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<ObjectSpec>> {
        let path = Path::new("dir/multi.toml");
        let file = SceneFile::parse(text, path)?;
        file.settings(path)?;
        specs(&file, path)
    }

    #[test]
    fn objects_take_their_own_maps_methods_and_placement() {
        let objects = parse(
            "[method]\nname = \"pom\"\n\
             [[object]]\ngeometry = \"cube\"\nposition = [1, 0, 2]\nscale = 0.5\nrotation = [0, 45, 0]\n\
             [object.heightmap]\nbundled = \"bricks\"\ndepth_scale = 0.05\n\
             [object.method]\nname = \"exact\"\n\
             [[object]]\ngeometry = \"sphere\"\n\
             [object.heightmap]\nbundled = \"rocks\"\n\
             [[object]]\ngeometry = \"torus\"\n",
        )
        .unwrap();
        assert_eq!(objects.len(), 3);
        let cube = objects[0].material.as_ref().unwrap();
        assert_eq!(cube.settings.method, dispmap::Method::Exact);
        assert_eq!(cube.settings.depth_scale, 0.05);
        assert_eq!(cube.settings.addressing, dispmap::Addressing::Clamp);
        assert_eq!(objects[0].placement.position, Vec3::new(1.0, 0.0, 2.0));
        assert_eq!(objects[0].placement.scale, 0.5);
        // The scene's [method] is the default of an object without its own.
        let sphere = objects[1].material.as_ref().unwrap();
        assert_eq!(sphere.settings.method, dispmap::Method::Pom);
        assert_eq!(sphere.settings.addressing, dispmap::Addressing::Repeat);
        assert!(objects[2].material.is_none());
    }

    #[test]
    fn bad_objects_name_the_object_the_key_and_the_file() {
        for (text, what) in [
            ("[[object]]\n[object.heightmap]\n", "object 1 geometry"),
            (
                "[[object]]\ngeometry = \"plane\"\nscale = 2\n[object.heightmap]\n",
                "object 1 position",
            ),
            ("[[object]]\ngeometry = \"cube\"\n", "at least one"),
            (
                "[[object]]\ngeometry = \"cube\"\n[object.heightmap]\n\
                 [[object]]\ngeometry = \"cube\"\nscale = -1\n",
                "object 2 scale",
            ),
            (
                "[[object]]\ngeometry = \"cube\"\n[object.method]\nname = \"exact\"\n",
                "object 1 heightmap",
            ),
            (
                "[[object]]\ngeometry = \"cube\"\nposition = [1, 2]\n[object.heightmap]\n",
                "three numbers",
            ),
            (
                "geometry = \"cube\"\n[[object]]\ngeometry = \"cube\"\n[object.heightmap]\n",
                "per object",
            ),
            (
                "[[object]]\ngeometry = \"cube\"\n[object.heightmap]\npath = \"x.png\"\n",
                "object 1 heightmap.convention",
            ),
            (
                "[[object]]\ngeometry = \"cube\"\n[object.heightmap]\ndepth_scale = -1\n",
                "object 1 depth-scale",
            ),
        ] {
            let err = parse(text).unwrap_err().to_string();
            assert!(
                err.contains(what) && err.contains("multi.toml"),
                "{what}: {err}"
            );
        }
    }
}
