//! The height channel of an OpenEXR file: which part and channel hold the height (a
//! documented rule for multi-part files), reading it with the `exr` crate, and messages
//! that give the real cause and name the part.
//!
//! The rule: the height is read from the first part (in file order) with a `Y` channel;
//! without one, from the first part with `R`, `G` and `B` channels (their Rec. 709
//! luminance, or the value when all three are equal); without one, from the first part
//! with an `R` channel. Deep parts are skipped. A single-part RGB file is read by the
//! `image` crate as before this module (the same values); everything else comes here.

use exr::prelude::{ReadChannels as _, ReadLayers as _, ReadSpecificChannel as _};

/// What a file's part holds for the height.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Channels {
    /// A `Y` channel.
    Y,
    /// `R`, `G` and `B`.
    Rgb,
    /// An `R` channel.
    R,
}

/// The part of a file chosen by the rule (module docs).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Part {
    /// Its index in the file.
    pub index: usize,
    /// How many parts the file has.
    pub parts: usize,
    /// Its name (`name` attribute), if any.
    pub name: Option<String>,
    /// Its channels used.
    pub channels: Channels,
    /// Its data window's size.
    pub width: usize,
    /// Its data window's size.
    pub height: usize,
}

impl Part {
    /// `part 1 'height' (Y)`, for messages and labels.
    pub fn describe(&self) -> String {
        let channels = match self.channels {
            Channels::Y => "channel Y",
            Channels::Rgb => "channels R, G, B",
            Channels::R => "channel R",
        };
        match &self.name {
            Some(n) => format!("part {} '{n}' of {} ({channels})", self.index, self.parts),
            None => format!("part {} of {} ({channels})", self.index, self.parts),
        }
    }
}

/// Reads the headers and chooses the part; `Err`: the cause, for the caller to put
/// after the file's name.
pub(crate) fn choose(file: impl std::io::Read) -> Result<Part, String> {
    let meta = exr::meta::MetaData::read_from_buffered(file, false)
        .map_err(|e| format!("cannot read the OpenEXR headers: {e}"))?;
    let parts = meta.headers.len();
    let has = |h: &exr::meta::header::Header, name: &str| {
        !h.deep && h.channels.list.iter().any(|c| c.name == *name)
    };
    let find =
        |test: &dyn Fn(&exr::meta::header::Header) -> bool| meta.headers.iter().position(test);
    let (index, channels) = if let Some(i) = find(&|h| has(h, "Y")) {
        (i, Channels::Y)
    } else if let Some(i) = find(&|h| has(h, "R") && has(h, "G") && has(h, "B")) {
        (i, Channels::Rgb)
    } else if let Some(i) = find(&|h| has(h, "R")) {
        (i, Channels::R)
    } else {
        let listing: Vec<String> = meta
            .headers
            .iter()
            .enumerate()
            .map(|(i, h)| {
                let names: Vec<String> =
                    h.channels.list.iter().map(|c| c.name.to_string()).collect();
                format!(
                    "part {i}{}: {}",
                    if h.deep { " (deep)" } else { "" },
                    if names.is_empty() {
                        "none".to_owned()
                    } else {
                        names.join(", ")
                    }
                )
            })
            .collect();
        return Err(format!(
            "no part has a Y, an R or R, G and B channels to read a height from ({})",
            listing.join("; ")
        ));
    };
    let header = &meta.headers[index];
    Ok(Part {
        index,
        parts,
        name: header
            .own_attributes
            .layer_name
            .as_ref()
            .map(|n| n.to_string()),
        channels,
        width: header.layer_size.width(),
        height: header.layer_size.height(),
    })
}

/// Reads the chosen part's height values, row by row (RGB as luminance); `Err`: the
/// `exr` crate's cause, naming the part.
pub(crate) fn read(bytes: &[u8], part: &Part) -> Result<Vec<f32>, String> {
    let fail = |e: exr::error::Error| format!("cannot decode {}: {e}", part.describe());
    let cursor = std::io::Cursor::new(bytes);
    // The pixel storage: the row width and the values, row by row.
    fn store<C>(size: exr::prelude::Vec2<usize>, _: &C) -> (usize, Vec<f32>) {
        (size.width(), vec![0f32; size.area()])
    }
    let values = match part.channels {
        Channels::Y | Channels::R => {
            let name = if part.channels == Channels::Y {
                "Y"
            } else {
                "R"
            };
            exr::prelude::read()
                .no_deep_data()
                .largest_resolution_level()
                .specific_channels()
                .required(name)
                .collect_pixels(
                    store,
                    |(width, values): &mut (usize, Vec<f32>),
                     at: exr::prelude::Vec2<usize>,
                     (v,): (f32,)| values[at.y() * *width + at.x()] = v,
                )
                .first_valid_layer()
                .all_attributes()
                .from_buffered(cursor)
                .map_err(fail)?
                .layer_data
                .channel_data
                .pixels
                .1
        }
        Channels::Rgb => {
            exr::prelude::read()
                .no_deep_data()
                .largest_resolution_level()
                .specific_channels()
                .required("R")
                .required("G")
                .required("B")
                .collect_pixels(
                    store,
                    |(width, values): &mut (usize, Vec<f32>),
                     at: exr::prelude::Vec2<usize>,
                     (r, g, b): (f32, f32, f32)| {
                        values[at.y() * *width + at.x()] = if r == g && g == b {
                            r
                        } else {
                            0.2126 * r + 0.7152 * g + 0.0722 * b
                        }
                    },
                )
                .first_valid_layer()
                .all_attributes()
                .from_buffered(cursor)
                .map_err(fail)?
                .layer_data
                .channel_data
                .pixels
                .1
        }
    };
    Ok(values)
}
