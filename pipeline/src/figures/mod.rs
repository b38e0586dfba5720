//! The report's figures, drawn with `plotters` into RGB bitmaps and encoded as PNG: training
//! curves ([`training_curves`]), the ablation spectrum ([`ablation`]) and risk-field heatmaps
//! ([`heatmap`]), the twin's fidelity over time ([`fidelity`]), shares with their intervals per kind ([`shares`]), each with a title, axes with units and a legend (heatmaps: metre axes and a
//! colour bar of risk values). Text is set in DejaVu Sans, embedded (its licence is
//! `assets/DejaVuSans-LICENSE.txt`), so a figure looks the same on every machine.

mod ablation;
mod canvas;
mod curves;
mod fidelity;
pub mod heatmap;
mod lines;
mod shares;

pub use ablation::ablation;
pub use canvas::{ABLATION_FILE, Bitmap, FigureError, TRAINING_CURVES_FILE, write_png};
pub use curves::training_curves;
pub use fidelity::fidelity;
pub use heatmap::HeatmapScene;
pub use lines::{Panel, Series, line_panels};
pub use shares::{ShareSeries, shares};
