//! EXR files of named float channels (`R`, `weight`, …) and 32-bit
//! unsigned integer channels (the exact sums of a part of a split render),
//! for data other programs need not read as a picture.
//! Written like every EXR here (atomically, header sorted, metadata as text
//! attributes); read back with the channels by name.

use std::collections::HashMap;
use std::path::Path;

use exr::prelude::{
    AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples, Image as ExrImage, Layer, Text,
    WritableImage,
};
use smallvec::SmallVec;

use super::{exr_layer_attributes, finish_exr, write_atomically, OutputError};

/// Writes `channels` (name, `width`×`height` samples row-major) and the
/// text `metadata` as one EXR layer, losslessly, atomically.
pub fn write_exr_channels(
    path: &Path,
    width: usize,
    height: usize,
    channels: Vec<(String, Vec<f32>)>,
    metadata: &[(String, String)],
) -> Result<(), OutputError> {
    write_channels(path, (width, height), channels, Vec::new(), metadata, false)
}

/// [`write_exr_channels`] with `words`, channels of 32-bit unsigned
/// integers (OpenEXR's `UINT`), beside the float ones.
pub fn write_exr_channels_with_words(
    path: &Path,
    width: usize,
    height: usize,
    channels: Vec<(String, Vec<f32>)>,
    words: Vec<(String, Vec<u32>)>,
    metadata: &[(String, String)],
) -> Result<(), OutputError> {
    write_channels(path, (width, height), channels, words, metadata, false)
}

/// [`write_exr_channels`] for an image: its `R`, `G`, `B` and any other
/// colour layers are linear Rec.709, which the standard `chromaticities`
/// attribute says, as on every RGB EXR written here.
pub fn write_exr_image_channels(
    path: &Path,
    width: usize,
    height: usize,
    channels: Vec<(String, Vec<f32>)>,
    metadata: &[(String, String)],
) -> Result<(), OutputError> {
    write_channels(path, (width, height), channels, Vec::new(), metadata, true)
}

fn write_channels(
    path: &Path,
    (width, height): (usize, usize),
    channels: Vec<(String, Vec<f32>)>,
    words: Vec<(String, Vec<u32>)>,
    metadata: &[(String, String)],
    rec709: bool,
) -> Result<(), OutputError> {
    let all = channels
        .into_iter()
        .map(|(name, v)| (name, FlatSamples::F32(v)))
        .chain(
            words
                .into_iter()
                .map(|(name, v)| (name, FlatSamples::U32(v))),
        );
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (name, samples) in all {
        if samples.len() != width * height {
            return Err(OutputError::InvalidImage {
                path: path.to_path_buf(),
                reason: format!("channel {name} does not hold {width}×{height} samples"),
            });
        }
        list.push(AnyChannel::new(Text::from(name.as_str()), samples));
    }
    let layer = Layer::new(
        (width, height),
        exr_layer_attributes(path, metadata)?,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(list),
    );
    let mut image = ExrImage::from_layer(layer);
    if rec709 {
        image.attributes.chromaticities = Some(super::REC709_CHROMATICITIES);
    }
    write_atomically(path, |writer| {
        image
            .write()
            .to_buffered(&mut *writer)
            .map_err(|source| OutputError::Exr {
                path: path.to_path_buf(),
                source,
            })?;
        finish_exr(path, writer)
    })
}

/// An EXR's first layer as named f32 channels and text attributes.
#[derive(Debug, Default)]
pub struct ChannelFile {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Samples by channel name (f16 channels converted to f32).
    pub channels: HashMap<String, Vec<f32>>,
    /// The 32-bit unsigned integer channels by name.
    pub words: HashMap<String, Vec<u32>>,
    /// Text attributes by name (UTF-8).
    pub text: HashMap<String, String>,
}

/// Reads the first layer of the EXR at `path`; the error names the file.
pub fn read_exr_channels(path: &Path) -> Result<ChannelFile, String> {
    let image = exr::prelude::read_first_flat_layer_from_file(path)
        .map_err(|e| format!("cannot read '{}' as OpenEXR: {e}", path.display()))?;
    let layer = image.layer_data;
    let mut file = ChannelFile {
        width: layer.size.width(),
        height: layer.size.height(),
        ..ChannelFile::default()
    };
    for channel in layer.channel_data.list {
        let name = channel.name.to_string();
        match channel.sample_data {
            FlatSamples::F32(v) => {
                file.channels.insert(name, v);
            }
            FlatSamples::F16(v) => {
                file.channels
                    .insert(name, v.into_iter().map(f32::from).collect());
            }
            FlatSamples::U32(v) => {
                file.words.insert(name, v);
            }
        }
    }
    for (key, value) in &layer.attributes.other {
        if let AttributeValue::Text(t) = value {
            let key = String::from_utf8_lossy(key.as_slice()).into_owned();
            file.text
                .insert(key, String::from_utf8_lossy(t.as_slice()).into_owned());
        }
    }
    Ok(file)
}
