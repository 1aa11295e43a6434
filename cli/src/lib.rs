//! dispmap's measurement lab and command-line tool, on top of the core `dispmap` crate:
//! the exact CPU reference ([`reference`](mod@reference)), the error metrics
//! ([`metrics`]), the measurement of a renderer's frames against the reference
//! ([`measure`]), the benchmark with its report and plots ([`bench`](mod@bench)), scene files
//! ([`scene_file`], [`scene_objects`]) and mesh loaders ([`mesh_file`]), heat and interval images
//! ([`heatmap`]), contact sheets and safe output files. The `dispmap` binary
//! (`src/main.rs`) is built from them. An engine depends on the core crate only.

#![warn(missing_docs)]

pub mod bench;
pub mod bundled;
pub mod contact_sheet;
pub mod frame_limit;
pub mod heatmap;
pub mod measure;
pub mod memory;
pub mod mesh_file;
pub mod metrics;
pub mod output;
pub mod reference;
pub mod scene_file;
pub mod scene_objects;
pub mod silhouette;
