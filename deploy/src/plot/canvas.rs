//! A drawing surface over [`RgbImage`]: filled rectangles, thick lines and bitmap text, all
//! clipped to the image, so chart code never indexes pixels itself.

use super::font::{ADVANCE, GLYPH_H, GLYPH_W, glyph};
use risktwin_common::risk::RgbImage;

pub type Rgb = [u8; 3];
pub const WHITE: Rgb = [255, 255, 255];
pub const BLACK: Rgb = [0, 0, 0];
pub const GREY: Rgb = [120, 120, 120];
pub const LIGHT_GREY: Rgb = [225, 225, 225];

/// An image being drawn on; coordinates in pixels, y down, (0, 0) top left.
pub struct Canvas {
    image: RgbImage,
}

impl Canvas {
    /// A white canvas.
    pub fn new(width: usize, height: usize) -> Self {
        Self { image: RgbImage { width, height, data: vec![255; width * height * 3] } }
    }

    pub fn into_image(self) -> RgbImage {
        self.image
    }

    fn put(&mut self, x: i64, y: i64, rgb: Rgb) {
        if x >= 0 && y >= 0 && (x as usize) < self.image.width && (y as usize) < self.image.height {
            let i = 3 * (y as usize * self.image.width + x as usize);
            self.image.data[i..i + 3].copy_from_slice(&rgb);
        }
    }

    /// Fills the rectangle [x0, x1) × [y0, y1) (corners in any order).
    pub fn fill_rect(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, rgb: Rgb) {
        let (xa, xb) = (x0.min(x1).round() as i64, x0.max(x1).round() as i64);
        let (ya, yb) = (y0.min(y1).round() as i64, y0.max(y1).round() as i64);
        for y in ya..yb {
            for x in xa..xb {
                self.put(x, y, rgb);
            }
        }
    }

    /// A line `thickness` pixels wide (square pen), sampled at half-pixel steps.
    pub fn line(&mut self, (x0, y0): (f64, f64), (x1, y1): (f64, f64), thickness: usize, rgb: Rgb) {
        if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite()) {
            return;
        }
        let steps = ((x1 - x0).abs().max((y1 - y0).abs()) * 2.0).ceil().clamp(1.0, 1e5) as usize;
        let half = thickness as i64 / 2;
        for k in 0..=steps {
            let t = k as f64 / steps as f64;
            let (x, y) = ((x0 + t * (x1 - x0)).round() as i64, (y0 + t * (y1 - y0)).round() as i64);
            for dy in 0..thickness as i64 {
                for dx in 0..thickness as i64 {
                    self.put(x + dx - half, y + dy - half, rgb);
                }
            }
        }
    }

    /// The rectangle's outline, one pixel wide.
    pub fn outline(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, rgb: Rgb) {
        for (a, b) in [((x0, y0), (x1, y0)), ((x1, y0), (x1, y1)), ((x1, y1), (x0, y1)), ((x0, y1), (x0, y0))] {
            self.line(a, b, 1, rgb);
        }
    }

    /// Draws `text` with its top-left corner at (x, y), each font pixel `scale` pixels wide.
    pub fn text(&mut self, x: f64, y: f64, text: &str, scale: usize, rgb: Rgb) {
        let (x, y) = (x.round() as i64, y.round() as i64);
        for (i, c) in text.chars().enumerate() {
            let left = x + (i * ADVANCE * scale) as i64;
            for (row, bits) in glyph(c).iter().enumerate() {
                for col in 0..GLYPH_W {
                    if bits >> (GLYPH_W - 1 - col) & 1 == 1 {
                        for dy in 0..scale {
                            for dx in 0..scale {
                                self.put(left + (col * scale + dx) as i64, y + (row * scale + dy) as i64, rgb);
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Width in pixels of `text` at `scale` (without the trailing gap).
pub fn text_width(text: &str, scale: usize) -> f64 {
    let n = text.chars().count();
    (n * ADVANCE * scale).saturating_sub(scale) as f64
}

/// Height in pixels of a line of text at `scale`.
pub fn text_height(scale: usize) -> f64 {
    (GLYPH_H * scale) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_sets_exactly_the_glyph_pixels() {
        let mut c = Canvas::new(20, 10);
        c.text(1.0, 1.0, "1", 1, BLACK);
        let img = c.into_image();
        let dark = (0..10).flat_map(|y| (0..20).map(move |x| (x, y))).filter(|&(x, y)| img.pixel(x, y) == BLACK);
        // "1" has 4 + 1×5 + 3 = 10 lit pixels (see the glyph table).
        assert_eq!(dark.count(), glyph('1').iter().map(|r| r.count_ones() as usize).sum::<usize>());
        assert_eq!(img.pixel(3, 1), BLACK, "top of the stem");
        assert_eq!(text_width("12", 2), 22.0);
    }

    #[test]
    fn drawing_outside_is_clipped() {
        let mut c = Canvas::new(4, 4);
        c.line((-10.0, -10.0), (10.0, 10.0), 3, BLACK);
        c.fill_rect(-5.0, -5.0, 2.0, 2.0, GREY);
        c.line((f64::NAN, 0.0), (1.0, 1.0), 1, BLACK);
        let img = c.into_image();
        assert_eq!(img.pixel(0, 0), GREY);
        assert_eq!(img.pixel(3, 3), BLACK);
        assert_eq!(img.pixel(3, 0), WHITE);
    }
}
