//! The plot of error on the model's pixels against frame time, one point per PoE (labelled)
//! and one line per cache, the aliasing floor a horizontal line (points under it are closer to
//! the true picture than full detail at one ray per pixel), with plotters: SVG through its SVG backend, PNG through [`Canvas`], an RGB8 backend
//! whose text is the 8 × 8 bitmap font (plotters' own bitmap text needs system fonts).

use std::convert::Infallible;
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::{
    BackendColor, BackendCoord, BackendTextStyle, DrawingBackend, DrawingErrorKind,
};

use super::{model_name, text, Row};
use crate::error::CliError;

const SIZE: (u32, u32) = (960, 640);

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Svg,
    Png,
}

impl Format {
    /// The format named by the file's extension (either case).
    pub fn of(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "svg" => Some(Format::Svg),
            "png" => Some(Format::Png),
            _ => None,
        }
    }
}

fn io_error(path: &Path, e: impl std::fmt::Display) -> CliError {
    CliError::Io {
        path: path.display().to_string(),
        source: std::io::Error::other(format!("plot: {e}")),
    }
}

/// Writes the plot of `rows` and the aliasing floor's RMSE `floor` to `path`, SVG or PNG by
/// its extension.
pub fn write(path: &Path, model: &Path, rows: &[Row], floor: f64) -> Result<(), CliError> {
    let title = format!("{}: error against frame time", model_name(model));
    match Format::of(path) {
        Some(Format::Svg) => {
            let mut svg = String::new();
            {
                let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
                draw(&root, &title, rows, floor).map_err(|e| io_error(path, e))?;
                root.present().map_err(|e| io_error(path, e))?;
            }
            std::fs::write(path, svg).map_err(|source| CliError::Io {
                path: path.display().to_string(),
                source,
            })
        }
        Some(Format::Png) => {
            let mut canvas = Canvas::new(SIZE.0, SIZE.1);
            {
                let root = (&mut canvas).into_drawing_area();
                draw(&root, &title, rows, floor).map_err(|e| io_error(path, e))?;
                root.present().map_err(|e| io_error(path, e))?;
            }
            oocfmt_trace::output::write_png(path, canvas.width, canvas.height, &canvas.rgb)
                .map_err(CliError::from)
        }
        None => Err(CliError::Usage(format!(
            "--plot {}: expected a file name ending in .svg or .png",
            path.display()
        ))),
    }
}

/// Draws the chart: x the warm frame time, y the RMSE on the model's pixels against the
/// reference, and the floor's RMSE as a horizontal line.
fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    rows: &[Row],
    floor: f64,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    let finite = |v: f64| if v.is_finite() { v } else { 0.0 };
    let floor = finite(floor);
    let max_x = rows.iter().map(|r| finite(r.ms)).fold(0.0, f64::max);
    let max_y = rows
        .iter()
        .map(|r| finite(r.error.model.rmse))
        .fold(floor, f64::max);
    // Room for the labels beside the points; a range is never empty.
    let x_hi = if max_x > 0.0 { max_x * 1.15 } else { 1.0 };
    let y_hi = if max_y > 0.0 { max_y * 1.15 } else { 1.0 };
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 26))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(64)
        .build_cartesian_2d(0.0..x_hi, 0.0..y_hi)?;
    chart
        .configure_mesh()
        .x_desc("frame ms (warm, median)")
        .y_desc("RMSE on the model's pixels against full detail supersampled")
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 16))
        .draw()?;
    // One series per cache and LOD kind.
    let mut series: Vec<(&str, &str)> = Vec::new();
    for r in rows {
        if !series.contains(&(r.cache.as_str(), r.lod)) {
            series.push((&r.cache, r.lod));
        }
    }
    for (i, &(cache, lod)) in series.iter().enumerate() {
        let colour = Palette99::pick(i).to_rgba();
        let mut points: Vec<(f64, f64, f32)> = rows
            .iter()
            .filter(|r| r.cache == cache && r.lod == lod)
            .map(|r| (finite(r.ms), finite(r.error.model.rmse), r.poe))
            .collect();
        points.sort_by(|a, b| a.2.total_cmp(&b.2));
        chart
            .draw_series(LineSeries::new(
                points.iter().map(|p| (p.0, p.1)),
                colour.stroke_width(2),
            ))?
            .label(format!("{cache} ({lod})"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
        chart.draw_series(points.iter().map(|&(x, y, poe)| {
            EmptyElement::at((x, y))
                + Circle::new((0, 0), 4, colour.filled())
                + Text::new(format!("poe {poe}"), (6, -16), ("sans-serif", 14))
        }))?;
    }
    let grey = RGBColor(96, 96, 96);
    chart
        .draw_series(LineSeries::new(
            [(0.0, floor), (x_hi, floor)],
            grey.stroke_width(1),
        ))?
        .label(format!(
            "aliasing floor: full detail, 1 ray/pixel (RMSE {floor:.2})"
        ))
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], grey));
    chart.draw_series(std::iter::once(
        EmptyElement::at((0.0, floor))
            + Text::new(
                "aliasing floor".to_string(),
                (6, -18),
                ("sans-serif", 14).into_font().color(&grey),
            ),
    ))?;
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 17))
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    Ok(())
}

/// An RGB8 picture as a plotters backend: shapes through plotters' own rasteriser, text in
/// the bitmap font.
pub struct Canvas {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<u8>,
}

impl Canvas {
    pub fn new(width: u32, height: u32) -> Canvas {
        Canvas {
            width,
            height,
            rgb: vec![255; 3 * width as usize * height as usize],
        }
    }

    fn blend(&mut self, (x, y): BackendCoord, c: BackendColor) {
        if x < 0 || y < 0 || x >= self.width as i32 || y >= self.height as i32 {
            return;
        }
        let at = 3 * (y as usize * self.width as usize + x as usize);
        let a = c.alpha.clamp(0.0, 1.0);
        if let Some(p) = self.rgb.get_mut(at..at + 3) {
            for (d, s) in p.iter_mut().zip([c.rgb.0, c.rgb.1, c.rgb.2]) {
                *d = (f64::from(s) * a + f64::from(*d) * (1.0 - a)).round() as u8;
            }
        }
    }
}

/// Font size to bitmap font scale: 8 × 8 glyphs grow by whole pixels.
fn scale(size: f64) -> u32 {
    (size / 16.0).round().clamp(1.0, 8.0) as u32
}

impl DrawingBackend for &mut Canvas {
    type ErrorType = Infallible;

    fn get_size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<Infallible>> {
        Ok(())
    }

    fn present(&mut self) -> Result<(), DrawingErrorKind<Infallible>> {
        Ok(())
    }

    fn draw_pixel(
        &mut self,
        point: BackendCoord,
        color: BackendColor,
    ) -> Result<(), DrawingErrorKind<Infallible>> {
        self.blend(point, color);
        Ok(())
    }

    fn draw_text<S: BackendTextStyle>(
        &mut self,
        s: &str,
        style: &S,
        pos: BackendCoord,
    ) -> Result<(), DrawingErrorKind<Infallible>> {
        let colour = style.color();
        let k = scale(style.size());
        let (w, h) = text::size(s, k);
        let (w, h) = (i64::from(w), i64::from(h));
        let anchor = style.anchor();
        let dx = match anchor.h_pos {
            HPos::Left => 0,
            HPos::Center => -w / 2,
            HPos::Right => -w,
        };
        let dy = match anchor.v_pos {
            VPos::Top => 0,
            VPos::Center => -h / 2,
            VPos::Bottom => -h,
        };
        let transform = style.transform();
        text::pixels(s, dx, dy, k, |x, y| {
            let (tx, ty) = transform.transform(x as i32, y as i32);
            self.blend((pos.0 + tx, pos.1 + ty), colour);
        });
        Ok(())
    }

    fn estimate_text_size<S: BackendTextStyle>(
        &self,
        s: &str,
        style: &S,
    ) -> Result<(u32, u32), DrawingErrorKind<Infallible>> {
        Ok(text::size(s, scale(style.size())))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_by_extension() {
        assert_eq!(Format::of(Path::new("a/curve.SVG")), Some(Format::Svg));
        assert_eq!(Format::of(Path::new("curve.png")), Some(Format::Png));
        assert_eq!(Format::of(Path::new("curve.jpg")), None);
        assert_eq!(Format::of(Path::new("curve")), None);
    }

    #[test]
    fn canvas_draws_text_and_blends() {
        let mut c = Canvas::new(64, 32);
        {
            let root = (&mut c).into_drawing_area();
            let _ = root.draw_text("Hi", &("sans-serif", 11).into_text_style(&root), (2, 2));
        }
        assert!(c.rgb.iter().any(|&v| v < 255));
        let mut d = Canvas::new(1, 1);
        d.blend(
            (0, 0),
            BackendColor {
                alpha: 0.5,
                rgb: (0, 0, 0),
            },
        );
        assert_eq!(d.rgb, vec![128; 3]);
        // Outside the picture: nothing happens.
        d.blend(
            (5, -1),
            BackendColor {
                alpha: 1.0,
                rgb: (0, 0, 0),
            },
        );
    }
}
