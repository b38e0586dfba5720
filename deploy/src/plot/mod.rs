//! Charts for the run report, drawn without a plotting dependency: line panels for training
//! curves and grouped bars for the ablation spectrum, into RGB images that `png_out` encodes.

mod axes;
pub mod bars;
mod canvas;
mod font;
pub mod lines;

pub use canvas::Rgb;

/// Matplotlib's "tab10" colours, one per variant or series.
pub const PALETTE: [Rgb; 5] = [[31, 119, 180], [255, 127, 14], [44, 160, 44], [214, 39, 40], [148, 103, 189]];
