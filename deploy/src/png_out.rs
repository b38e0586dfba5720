//! PNG encoding of rendered images (the rendering itself is pure, in `common::risk`).

use crate::error::{CliError, CliResult};
use risktwin_common::risk::RgbImage;
use std::io::BufWriter;
use std::path::Path;

/// Writes an 8-bit RGB image.
pub fn write_png(path: &Path, image: &RgbImage) -> CliResult {
    let file =
        std::fs::File::create(path).map_err(|e| CliError::input(format!("cannot create {}: {e}", path.display())))?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), image.width as u32, image.height as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| CliError::runtime(format!("{}: {e}", path.display())))?;
    writer.write_image_data(&image.data).map_err(|e| CliError::runtime(format!("{}: {e}", path.display())))?;
    writer.finish().map_err(|e| CliError::runtime(format!("{}: {e}", path.display())))
}
