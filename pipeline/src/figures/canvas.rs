//! What every figure is drawn on: the embedded font, the palette, the RGB bitmap and its PNG
//! file. Its own module so that the figures import it without importing `figures/mod.rs`.

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::{FontStyle, RGBColor, register_font};
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Once;

/// File name of the training curves in the report folder.
pub const TRAINING_CURVES_FILE: &str = "training_curves.png";
/// File name of the ablation spectrum in the report folder.
pub const ABLATION_FILE: &str = "ablation.png";

/// The font family every figure's text uses.
pub(super) const FONT: &str = "sans-serif";
/// DejaVu Sans (Bitstream Vera licence, see assets/DejaVuSans-LICENSE.txt).
static DEJAVU_SANS: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

/// Matplotlib's "tab10" colours, one per variant or series.
pub(super) const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Why a figure could not be drawn or written.
#[derive(Debug, thiserror::Error)]
pub enum FigureError {
    /// plotters refused to draw (its message).
    #[error("drawing the figure: {0}")]
    Draw(String),
    #[error("cannot create {}: {source}", path.display())]
    Create { path: PathBuf, source: std::io::Error },
    #[error("{}: {source}", path.display())]
    Encode { path: PathBuf, source: png::EncodingError },
}

impl FigureError {
    pub(super) fn draw(e: impl std::fmt::Display) -> Self {
        FigureError::Draw(e.to_string())
    }
}

/// An 8-bit RGB image, rows top to bottom, 3 bytes per pixel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Bitmap {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<u8>,
}

impl Bitmap {
    /// A white image.
    pub(super) fn new(width: u32, height: u32) -> Self {
        Bitmap { width, height, rgb: vec![255; 3 * width as usize * height as usize] }
    }

    /// The pixel at (x, y), y = 0 at the top.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }
}

/// The legend of a bar chart (the ablation, the shares): upper right, on a light box.
pub(super) fn bar_legend<'a, 'b: 'a>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
) -> Result<(), FigureError> {
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FONT, 15))
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK.mix(0.4))
        .draw()
        .map_err(FigureError::draw)
}

/// Makes the embedded font known to plotters (once per process).
pub(super) fn register_fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let registered = register_font(FONT, FontStyle::Normal, DEJAVU_SANS);
        assert!(registered.is_ok(), "the embedded DejaVu Sans is a valid TrueType font");
    });
}

/// Writes `image` as an 8-bit RGB PNG.
pub fn write_png(path: &Path, image: &Bitmap) -> Result<(), FigureError> {
    let file =
        std::fs::File::create(path).map_err(|source| FigureError::Create { path: path.to_path_buf(), source })?;
    let encode = |source| FigureError::Encode { path: path.to_path_buf(), source };
    let mut encoder = png::Encoder::new(BufWriter::new(file), image.width, image.height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(encode)?;
    writer.write_image_data(&image.rgb).map_err(encode)?;
    writer.finish().map_err(encode)
}
