//! Heatmaps of per-ray cost: the camera rays of a view traced with a [`RayCost`] record, one
//! count per pixel drawn in false colour (the cost-per-pixel figures of Mora 2011, Fig. 8, and
//! Wiche 2020, Fig. 1), with a colour bar whose scale is labelled.
//!
//! Built on the [`Tracer`] contract only, so it draws every registered tracer: a tracer that does
//! not fill the record yet gives a uniform image with a scale of 0 to 0.
//!
//! The colour map is viridis (perceptually uniform, readable in grey and by most colour-blind
//! readers), from matplotlib's nine evenly spaced stops, interpolated linearly; the scale is
//! linear from the smallest to the largest count of the view.

use super::Image;
use crate::error::{Error, Result};
use crate::rays::{Camera, HitBatch};
use crate::scene::Scene;
use crate::tracer::{RayCost, Stats, Tracer};
use std::time::Instant;

/// Which per-ray count to draw (the fields of [`RayCost`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CostKind {
    /// Acceleration nodes the ray entered.
    Nodes,
    /// Every test the ray took part in.
    Tests,
    /// Ray/triangle tests.
    Triangles,
}

impl CostKind {
    /// All kinds, in the order the CLI lists them.
    pub const ALL: [CostKind; 3] = [CostKind::Nodes, CostKind::Tests, CostKind::Triangles];

    /// The name (`nodes`, `tests`, `triangles`), as [`RayCost::by_name`] takes it.
    pub fn name(self) -> &'static str {
        match self {
            CostKind::Nodes => "nodes",
            CostKind::Tests => "tests",
            CostKind::Triangles => "triangles",
        }
    }
}

impl std::str::FromStr for CostKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                Error::Invalid(format!(
                    "unknown heatmap {s:?}; expected nodes, tests or triangles"
                ))
            })
    }
}

/// The scale of a heatmap: the smallest, largest and mean count over its pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct HeatScale {
    /// Smallest count (the bottom of the bar).
    pub min: u32,
    /// Largest count (the top of the bar).
    pub max: u32,
    /// Mean count per ray.
    pub mean: f64,
}

impl HeatScale {
    /// The scale of `values` (all zeros for none).
    pub fn of(values: &[u32]) -> Self {
        if values.is_empty() {
            return Self::default();
        }
        let (min, max, sum) = values.iter().fold((u32::MAX, 0, 0u64), |(a, b, s), &v| {
            (a.min(v), b.max(v), s + v as u64)
        });
        Self {
            min,
            max,
            mean: sum as f64 / values.len() as f64,
        }
    }

    /// Where `v` lies on the scale, 0 (min) to 1 (max); 0 when the scale is one value.
    fn position(&self, v: u32) -> f32 {
        if self.max <= self.min {
            0.0
        } else {
            (v.saturating_sub(self.min) as f64 / (self.max - self.min) as f64) as f32
        }
    }
}

/// A drawn heatmap.
#[derive(Clone, Debug)]
pub struct Heatmap {
    /// The image: the view (`width × height`) with the colour bar to its right
    /// (`width + bar_width(height)` wide).
    pub image: Image,
    /// The drawn count per pixel, ordered `j·width + i`.
    pub values: Vec<u32>,
    /// Its scale.
    pub scale: HeatScale,
    /// What was drawn.
    pub kind: CostKind,
    /// The trace's stats (with its wall time).
    pub stats: Stats,
    /// Camera rays that hit.
    pub hits: u64,
}

/// Traces the camera rays of a `width × height` view of `scene` (the tracer prepared for it) with
/// a per-ray cost record and draws the count `kind` in false colour, with a colour bar.
pub fn heatmap(
    scene: &Scene,
    tracer: &dyn Tracer,
    camera: &Camera,
    width: u32,
    height: u32,
    kind: CostKind,
) -> Result<Heatmap> {
    let rays = camera.rays(width, height);
    let mut hits = HitBatch::new(0);
    let mut cost = RayCost::default();
    let t0 = Instant::now();
    let mut stats = tracer.intersect(scene, &rays, &mut hits, Some(&mut cost))?;
    stats.trace_ms = t0.elapsed().as_secs_f64() * 1e3;
    let values = cost.by_name(kind.name()).unwrap_or_default().to_vec();
    if values.len() != rays.len() {
        return Err(Error::Invalid(format!(
            "tracer {}: {} cost records for {} rays (the contract asks for one per ray)",
            tracer.name(),
            values.len(),
            rays.len()
        )));
    }
    let scale = HeatScale::of(&values);
    Ok(Heatmap {
        image: draw(&values, width, height, &scale),
        hits: hits.hit_count() as u64,
        values,
        scale,
        kind,
        stats,
    })
}

/// Width in pixels of the colour bar (stripe and labels) drawn beside an image `height` tall.
pub fn bar_width(height: u32) -> u32 {
    BAR_UNITS * font_scale(height)
}

/// Draws `values` (`width × height`, row-major) on `scale`, with the colour bar to the right.
pub fn draw(values: &[u32], width: u32, height: u32, scale: &HeatScale) -> Image {
    let bar = bar_width(height);
    let full = width + bar;
    let mut img = Image {
        width: full,
        height,
        rgb: vec![0; 3 * full as usize * height as usize],
    };
    for j in 0..height {
        for i in 0..width {
            let v = values[(j * width + i) as usize];
            put(&mut img, i, j, viridis(scale.position(v)));
        }
    }
    draw_bar(&mut img, width, scale);
    img
}

/// The viridis colour at `t` in [0, 1] (clamped).
pub fn viridis(t: f32) -> [u8; 3] {
    let x = t.clamp(0.0, 1.0) * (VIRIDIS.len() - 1) as f32;
    let k = (x as usize).min(VIRIDIS.len() - 2);
    let f = x - k as f32;
    let (a, b) = (VIRIDIS[k], VIRIDIS[k + 1]);
    std::array::from_fn(|c| (a[c] as f32 + (b[c] as f32 - a[c] as f32) * f + 0.5) as u8)
}

/// matplotlib's viridis at 0, 1/8, ..., 1.
const VIRIDIS: [[u8; 3]; 9] = [
    [0x44, 0x01, 0x54],
    [0x47, 0x2d, 0x7b],
    [0x3b, 0x52, 0x8b],
    [0x2c, 0x72, 0x8e],
    [0x21, 0x91, 0x8c],
    [0x28, 0xae, 0x80],
    [0x5e, 0xc9, 0x62],
    [0xad, 0xdc, 0x30],
    [0xfd, 0xe7, 0x25],
];

// The bar, in font pixels (scaled by `font_scale`): margin, stripe, gap, six characters of four
// pixels, margin.
const MARGIN: u32 = 3;
const STRIPE: u32 = 8;
const GAP: u32 = 3;
const LABEL_CHARS: u32 = 6;
const BAR_UNITS: u32 = MARGIN + STRIPE + GAP + 4 * LABEL_CHARS + MARGIN;
const BAR_BACKGROUND: [u8; 3] = [24, 24, 28];
const LABEL_COLOUR: [u8; 3] = [235, 235, 235];

/// Font pixels per image pixel: 2 on views 160 pixels tall or more.
fn font_scale(height: u32) -> u32 {
    if height >= 160 {
        2
    } else {
        1
    }
}

fn put(img: &mut Image, i: u32, j: u32, c: [u8; 3]) {
    if i < img.width && j < img.height {
        let k = 3 * (j as usize * img.width as usize + i as usize);
        img.rgb[k..k + 3].copy_from_slice(&c);
    }
}

/// The stripe (max at the top, min at the bottom) and its labels (max, middle, min where they
/// fit), in the columns right of `x0`.
fn draw_bar(img: &mut Image, x0: u32, scale: &HeatScale) {
    let h = img.height;
    let s = font_scale(h);
    for j in 0..h {
        for i in x0..img.width {
            put(img, i, j, BAR_BACKGROUND);
        }
    }
    // The stripe spans the rows [top, bottom], leaving room for half a label above and below.
    let (top, bottom) = (3 * s, h.saturating_sub(3 * s + 1));
    if bottom <= top {
        return;
    }
    let span = (bottom - top) as f32;
    for j in top..=bottom {
        let t = if scale.max > scale.min {
            1.0 - (j - top) as f32 / span
        } else {
            0.0
        };
        for i in 0..STRIPE * s {
            put(img, x0 + MARGIN * s + i, j, viridis(t));
        }
    }
    // Labels, centred on their row; three when there is room for three, else two, else none.
    let glyph_h = 5 * s;
    let room = bottom - top;
    let mut labels = vec![(scale.max, top), (scale.min, bottom)];
    if room >= 4 * glyph_h {
        let mid = scale.min + (scale.max - scale.min) / 2;
        let row = bottom - ((scale.position(mid) * span) as u32).min(room);
        labels.push((mid, row));
    } else if room < 2 * glyph_h {
        return;
    }
    let x = x0 + (MARGIN + STRIPE + GAP) * s;
    for (v, row) in labels {
        let y = row
            .saturating_sub(glyph_h / 2)
            .min(h.saturating_sub(glyph_h));
        draw_text(img, x, y, &label(v), s);
    }
}

/// A count in at most six characters, rounded down: `12345`, `12345k`, `4294M`.
fn label(v: u32) -> String {
    if v < 100_000 {
        v.to_string()
    } else if v < 100_000_000 {
        format!("{}k", v / 1000)
    } else {
        format!("{}M", v / 1_000_000)
    }
}

fn draw_text(img: &mut Image, x: u32, y: u32, text: &str, s: u32) {
    for (n, ch) in text.chars().enumerate() {
        let rows = glyph(ch);
        for (r, bits) in rows.iter().enumerate() {
            for c in 0..3u32 {
                if bits & (0b100 >> c) != 0 {
                    for dy in 0..s {
                        for dx in 0..s {
                            put(
                                img,
                                x + (4 * n as u32 + c) * s + dx,
                                y + r as u32 * s + dy,
                                LABEL_COLOUR,
                            );
                        }
                    }
                }
            }
        }
    }
}

/// A 3×5 glyph, one row of three bits (left = 0b100) per line, for the digits and `k`, `M`.
fn glyph(c: char) -> [u8; 5] {
    match c {
        '0' => [0b111, 0b101, 0b101, 0b101, 0b111],
        '1' => [0b010, 0b110, 0b010, 0b010, 0b111],
        '2' => [0b111, 0b001, 0b111, 0b100, 0b111],
        '3' => [0b111, 0b001, 0b111, 0b001, 0b111],
        '4' => [0b101, 0b101, 0b111, 0b001, 0b001],
        '5' => [0b111, 0b100, 0b111, 0b001, 0b111],
        '6' => [0b111, 0b100, 0b111, 0b101, 0b111],
        '7' => [0b111, 0b001, 0b010, 0b010, 0b010],
        '8' => [0b111, 0b101, 0b111, 0b101, 0b111],
        '9' => [0b111, 0b101, 0b111, 0b001, 0b111],
        'k' => [0b100, 0b101, 0b110, 0b101, 0b101],
        'M' => [0b101, 0b111, 0b111, 0b101, 0b101],
        _ => [0; 5],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::procedural;
    use crate::tracers;

    fn map(tracer: &str, kind: CostKind, w: u32, h: u32) -> (Scene, Heatmap) {
        let scene = procedural::open("sphere:500").unwrap();
        let mut t = tracers::create(tracer, &[]).unwrap();
        t.prepare(&scene).unwrap();
        let cam = Camera::framing(&scene.bounds(), 40.0, w as f32 / h as f32);
        let m = heatmap(&scene, t.as_ref(), &cam, w, h, kind).unwrap();
        (scene, m)
    }

    #[test]
    fn naive_tests_every_triangle_for_every_ray() {
        let (scene, m) = map("naive", CostKind::Triangles, 24, 16);
        assert!(m.values.iter().all(|&v| v as usize == scene.len()));
        let n = scene.len() as u32;
        assert_eq!((m.scale.min, m.scale.max, m.scale.mean), (n, n, n as f64));
        // One value: every pixel of the view has one colour.
        let px = |i: u32, j: u32| {
            let k = 3 * (j * m.image.width + i) as usize;
            [m.image.rgb[k], m.image.rgb[k + 1], m.image.rgb[k + 2]]
        };
        assert!((0..16).all(|j| (0..24).all(|i| px(i, j) == px(0, 0))));
    }

    #[test]
    fn bvh_cost_differs_between_the_mesh_and_the_background() {
        let (w, h) = (40, 40);
        let (_, m) = map("bvh", CostKind::Nodes, w, h);
        assert!(m.hits > 0 && m.hits < (w * h) as u64);
        let centre = m.values[(h / 2 * w + w / 2) as usize];
        let corner = m.values[0];
        assert!(centre > corner, "nodes: centre {centre}, corner {corner}");
        let k = |i: u32, j: u32| 3 * (j * m.image.width + i) as usize;
        assert_ne!(
            m.image.rgb[k(w / 2, h / 2)..k(w / 2, h / 2) + 3],
            m.image.rgb[k(0, 0)..k(0, 0) + 3]
        );
        assert!(m.scale.min <= corner && centre <= m.scale.max);
        assert!(m.scale.mean > m.scale.min as f64 && m.scale.mean < m.scale.max as f64);
    }

    #[test]
    fn image_is_the_view_plus_the_bar() {
        for (w, h) in [(24, 16), (64, 200)] {
            let (_, m) = map("bvh", CostKind::Tests, w, h);
            assert_eq!((m.image.width, m.image.height), (w + bar_width(h), h));
            assert_eq!(
                m.image.rgb.len(),
                3 * (w + bar_width(h)) as usize * h as usize
            );
        }
        assert_eq!(bar_width(200), 2 * bar_width(100));
    }

    #[test]
    fn scale_labels_and_colours() {
        assert_eq!(label(0), "0");
        assert_eq!(label(99_999), "99999");
        assert_eq!(label(123_456), "123k");
        assert_eq!(label(u32::MAX), "4294M");
        assert!([0, 99_999, 100_000, 99_999_999, u32::MAX]
            .iter()
            .all(|&v| label(v).len() <= LABEL_CHARS as usize));
        assert_eq!(viridis(0.0), VIRIDIS[0]);
        assert_eq!(viridis(1.0), VIRIDIS[8]);
        assert_eq!(viridis(0.5), VIRIDIS[4]);
        assert_eq!(viridis(-1.0), VIRIDIS[0]);
        assert_eq!(
            "triangles".parse::<CostKind>().unwrap(),
            CostKind::Triangles
        );
        assert!("foo".parse::<CostKind>().is_err());
        assert_eq!(HeatScale::of(&[]), HeatScale::default());
    }
}
