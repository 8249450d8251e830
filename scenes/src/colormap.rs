//! Heat maps: one-channel images (traversal costs per pixel) drawn with a perceptual colour
//! map, side by side on one colour scale, with a legend bar that has the scale written on it.
//!
//! The colour map is viridis (van der Walt and Smith, matplotlib 2015: perceptually uniform,
//! readable in grey and by colour-blind viewers), taken from the `colorous` crate. Values are
//! mapped linearly from 0 to the scale's maximum; larger values get the top colour, and NaN
//! or negative values the bottom one. Labels are drawn with [`crate::font`].

use crate::font::{GLYPH_H, draw_text, text_width};
use crate::image::{Rgb8Image, ScalarImage};

/// Background of strips and legends.
pub const BACKGROUND: [u8; 3] = [24, 24, 24];
/// Colour of the labels.
pub const TEXT: [u8; 3] = [235, 235, 235];

/// The viridis colour of `t` in `[0, 1]` (clamped; NaN as 0).
pub fn viridis(t: f32) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let c = colorous::VIRIDIS.eval_continuous(f64::from(t));
    [c.r, c.g, c.b]
}

/// `image` in viridis, 0 to `max` (a non-positive or non-finite `max` draws everything in
/// the bottom colour).
pub fn heatmap(image: &ScalarImage, max: f32) -> Rgb8Image {
    let scale = if max.is_finite() && max > 0.0 { 1.0 / max } else { 0.0 };
    let rgb = image.values.iter().flat_map(|&v| viridis(v * scale)).collect();
    Rgb8Image { width: image.width, height: image.height, rgb }
}

/// The largest finite value of all `images` (0 if none): a common scale for a strip.
pub fn common_max<'a>(images: impl IntoIterator<Item = &'a ScalarImage>) -> f32 {
    images.into_iter().filter_map(|i| i.finite_range().map(|r| r.1)).fold(0.0, f32::max)
}

/// A legend tick's text: up to three significant digits, no trailing zeros (`0`, `12.5`,
/// `250`, `0.125`, `1.2e+04`).
pub fn tick_label(v: f32) -> String {
    let a = v.abs();
    let s = if a == 0.0 {
        return "0".into();
    } else if a >= 10_000.0 {
        return format!("{v:.1e}").replace('e', "e+");
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 10.0 {
        format!("{v:.1}")
    } else if a >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    };
    if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
}

/// One image of a strip, with the label drawn above it.
#[derive(Clone, Copy, Debug)]
pub struct Panel<'a> {
    /// The label (a method name).
    pub label: &'a str,
    /// The values.
    pub image: &'a ScalarImage,
}

/// Space between panels and around the strip, in pixels.
const MARGIN: u32 = 8;
/// Ticks on the legend bar (0, max/4, ..., max).
const TICKS: u32 = 4;

/// Side by side heat maps of `panels`, all from 0 to `max`, each with its label above it, and
/// a legend bar on the right: the colour scale with its values written at 0, 1/4, ..., max and
/// `title` (e.g. `NODES / RAY`) above it. Text is twice as large for panels at least 256
/// pixels high.
pub fn strip(panels: &[Panel<'_>], max: f32, title: &str) -> Rgb8Image {
    let panel_h = panels.iter().map(|p| p.image.height).max().unwrap_or(0).max(32);
    let s = if panel_h >= 256 { 2 } else { 1 };
    // Room for the labels, and for half a tick label above the bar's top.
    let band = GLYPH_H * s * 3 / 2 + MARGIN;
    let panels_w: u32 = panels.iter().map(|p| p.image.width.max(text_width(p.label, s)) + MARGIN).sum();
    let bar_w = 12 * s;
    let ticks: Vec<String> = (0..=TICKS).map(|k| tick_label(max * k as f32 / TICKS as f32)).collect();
    let ticks_w = ticks.iter().map(|t| text_width(t, s)).max().unwrap_or(0);
    let legend_w = (bar_w + 5 * s + ticks_w).max(text_width(title, s));
    let width = MARGIN + panels_w + legend_w + MARGIN;
    let height = band + panel_h + MARGIN + GLYPH_H * s / 2;
    let mut out = Rgb8Image::filled(width, height, BACKGROUND);
    let top = i64::from(band);
    let mut x = i64::from(MARGIN);
    for p in panels {
        draw_text(&mut out, x, i64::from(MARGIN / 2), p.label, s, TEXT);
        out.blit(&heatmap(p.image, max), x, top);
        x += i64::from(p.image.width.max(text_width(p.label, s)) + MARGIN);
    }
    draw_text(&mut out, x, i64::from(MARGIN / 2), title, s, TEXT);
    let rows = panel_h.max(2) - 1;
    for r in 0..panel_h {
        out.fill_rect(x, top + i64::from(r), bar_w, 1, viridis(1.0 - r as f32 / rows as f32));
    }
    for (k, label) in ticks.iter().enumerate() {
        let y = top + i64::from(rows - rows * k as u32 / TICKS);
        out.fill_rect(x + i64::from(bar_w), y, 2 * s, 1, TEXT);
        let text_y = y - i64::from(GLYPH_H * s / 2);
        draw_text(&mut out, x + i64::from(bar_w + 5 * s), text_y, label, s, TEXT);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn viridis_runs_from_purple_to_yellow() {
        assert_eq!(viridis(0.0), [68, 1, 84]);
        assert_eq!(viridis(1.0), [253, 231, 37]);
        assert_eq!(viridis(f32::NAN), viridis(0.0));
        assert_eq!(viridis(7.0), viridis(1.0));
        // Perceptually ordered: lightness (here the channel sum) grows along the map.
        let sums: Vec<u32> = (0..=10).map(|i| viridis(i as f32 / 10.0).iter().map(|&c| u32::from(c)).sum()).collect();
        assert!(sums.windows(2).all(|w| w[0] < w[1]), "{sums:?}");
    }

    #[test]
    fn heatmap_maps_zero_to_max() {
        let image = ScalarImage { width: 3, height: 1, values: vec![0.0, 2.0, 4.0] };
        let h = heatmap(&image, 4.0);
        assert_eq!((h.get(0, 0), h.get(1, 0), h.get(2, 0)), (viridis(0.0), viridis(0.5), viridis(1.0)));
        assert_eq!(heatmap(&image, 0.0).get(2, 0), viridis(0.0), "no scale: bottom colour");
        let other = ScalarImage { width: 1, height: 1, values: vec![f32::INFINITY] };
        assert_eq!(common_max([&image, &other]), 4.0);
    }

    #[test]
    fn ticks_are_short() {
        assert_eq!(tick_label(0.0), "0");
        assert_eq!(tick_label(12.5), "12.5");
        assert_eq!(tick_label(250.0), "250");
        assert_eq!(tick_label(0.125), "0.125");
        assert_eq!(tick_label(3.0), "3");
        assert_eq!(tick_label(12500.0), "1.2e+4");
    }

    /// The strip holds each panel's heat map at its place, the legend bar runs from the top
    /// colour down to the bottom one, and labels are drawn.
    #[test]
    fn strip_places_panels_and_legend() {
        let a = ScalarImage { width: 40, height: 30, values: vec![1.0; 1200] };
        let b = ScalarImage { width: 40, height: 30, values: vec![2.0; 1200] };
        let out = strip(&[Panel { label: "MONO", image: &a }, Panel { label: "MFT-16", image: &b }], 2.0, "NODES");
        let top = GLYPH_H * 3 / 2 + MARGIN;
        assert_eq!(out.height, top + 32 + MARGIN + GLYPH_H / 2);
        assert_eq!(out.get(MARGIN + 5, top + 5), viridis(0.5));
        assert_eq!(out.get(2 * MARGIN + 40 + 5, top + 5), viridis(1.0));
        let bar_x = 3 * MARGIN + 80;
        assert_eq!(out.get(bar_x + 2, top), viridis(1.0));
        assert_eq!(out.get(bar_x + 2, top + 31), viridis(0.0));
        let label_pixels = (0..out.width).filter(|&x| (0..top).any(|y| out.get(x, y) == TEXT)).count();
        assert!(label_pixels > 20, "labels drawn");
    }
}
