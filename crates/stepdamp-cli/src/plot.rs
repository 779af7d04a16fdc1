//! Plots: velocity error against speed (the analogue of the patent's figs. 4–7).

use anyhow::{Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;
use stepdamp_identify::validation::Validation;
use stepdamp_sim::SweepRow;

static FONT: Once = Once::new();

/// Registers the embedded DejaVu Sans as "sans-serif" (bitmap text needs a font file;
/// embedding it means no system font library is needed).
pub fn register_font() {
    FONT.call_once(|| {
        // The font is valid: the embedded bytes are tested.
        let _ =
            plotters::style::register_font("sans-serif", FontStyle::Normal, include_bytes!("../assets/DejaVuSans.ttf"));
    });
}

/// Text from outside (a profile's name, a log's path) as drawn: one printable line
/// ([`stepdamp_export::escape::line`]). The SVG backend (plotters-svg 0.3.7,
/// `escape_and_push`) writes `& < > " '` as entities itself; XML 1.0 cannot carry control
/// characters at all, so they are shown escaped. The hostile-name test parses the SVG.
fn shown(s: &str) -> String {
    stepdamp_export::escape::line(s)
}

/// A vertical marker: x position and label.
pub struct Marker {
    /// Speed in rad/s.
    pub x: f64,
    /// Label.
    pub label: String,
}

const PALETTE: [RGBColor; 4] =
    [RGBColor(200, 40, 40), RGBColor(30, 90, 200), RGBColor(20, 150, 60), RGBColor(150, 60, 170)];

/// A figure that can be drawn on any plotters backend.
pub trait Figure {
    /// Draws the whole figure on `root`.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static;
}

/// The one render path: draws `fig` into `svg` and `png` (pixels `size`), each presented
/// and its error naming the file.
pub fn render(fig: &impl Figure, size: (u32, u32), svg: &Path, png: &Path) -> Result<()> {
    register_font();
    {
        let root = SVGBackend::new(svg, size).into_drawing_area();
        fig.draw(&root)?;
        root.present().map_err(|e| anyhow!("{}: {e}", svg.display()))?;
    }
    let root = BitMapBackend::new(png, size).into_drawing_area();
    fig.draw(&root)?;
    root.present().map_err(|e| anyhow!("{}: {e}", png.display()))?;
    Ok(())
}

struct Sweep<'a> {
    rows: &'a [SweepRow],
    markers: &'a [Marker],
    title: &'a str,
}

impl Figure for Sweep<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        draw_sweep(root, self.rows, self.markers, self.title)
    }
}

/// Writes the sweep plot as SVG and PNG.
pub fn sweep_plot(rows: &[SweepRow], markers: &[Marker], title: &str, svg: &Path, png: &Path) -> Result<()> {
    render(&Sweep { rows, markers, title }, (1000, 700), svg, png)
}

/// The validation of a fit ([`stepdamp_identify::validation`]): per run, the effort ripple
/// the model leaves unexplained at each order, as grouped bars (mN·m, log scale).
pub struct ValidationFigure<'a> {
    /// The validation.
    pub validation: &'a Validation,
    /// Title.
    pub title: &'a str,
}

impl Figure for ValidationFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("plot: {e}");
        root.fill(&WHITE).map_err(err)?;
        let v = self.validation;
        let max_order = f64::from(v.max_order);
        let values = || v.runs.iter().flat_map(|r| r.unexplained.iter().map(|o| 1e3 * o.amplitude_nm));
        let positive = || values().filter(|x| x.is_finite() && *x > 0.0);
        let top = positive().fold(1e-6, f64::max) * 2.0;
        let floor = positive().fold(top, f64::min).max(top * 1e-5) / 2.0;
        let mut chart = ChartBuilder::on(root)
            .caption(shown(self.title), ("sans-serif", 20))
            .margin(14)
            .x_label_area_size(40)
            .y_label_area_size(80)
            .build_cartesian_2d(0.5f64..max_order + 0.5, (floor..top).log_scale())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("harmonic order k of the electrical angle")
            .y_desc("unexplained effort ripple (mN·m)")
            .x_labels(usize::from(v.max_order))
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_label_formatter(&|y| format!("{y:.1e}"))
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(err)?;
        let n = v.runs.len().max(1) as f64;
        let width = 0.76 / n;
        for (ri, run) in v.runs.iter().enumerate() {
            let color = PALETTE[ri % PALETTE.len()];
            let x_off = -0.38 + width * ri as f64;
            chart
                .draw_series(run.unexplained.iter().map(|o| {
                    let k = f64::from(o.order);
                    let y = (1e3 * o.amplitude_nm).max(floor);
                    Rectangle::new([(k + x_off, floor), (k + x_off + width * 0.9, y)], color.filled())
                }))
                .map_err(err)?
                .label(format!("{}: explains {:.1} %", shown(&run.source), 100.0 * run.explained_share))
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], color.filled()));
        }
        legend(&mut chart)?;
        Ok(())
    }
}

fn draw_sweep<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    rows: &[SweepRow],
    markers: &[Marker],
    title: &str,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("plot: {e}");
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(&shown(title), ("sans-serif", 22)).map_err(err)?;
    let (modes, comps) = stepdamp_sim::summary::modes_and_compensations(rows);
    let panels = root.split_evenly((modes.len().max(1), 1));
    let (x0, x1) = rows
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), r| (a.min(r.speed_cmd_rad_s), b.max(r.speed_cmd_rad_s)));
    let finite = |v: f64| v.is_finite() && v > 0.0;
    let (y0, y1) = rows
        .iter()
        .map(|r| r.vel_err_pp_rad_s)
        .filter(|&v| finite(v))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !(x0.is_finite() && y0.is_finite()) {
        return Err(anyhow!("plot: no finite data"));
    }
    let (y0, y1) = (y0 / 2.0, y1 * 2.0);
    let xpad = 0.02 * (x1 - x0).max(1e-9);
    for (panel, mode) in panels.iter().zip(&modes) {
        let mut chart = ChartBuilder::on(panel)
            .caption(format!("{mode}: velocity error, peak to peak"), ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(x0 - xpad..x1 + xpad, (y0..y1).log_scale())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("commanded speed (rad/s)")
            .y_desc("ω − ω_cmd peak-to-peak (rad/s)")
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(err)?;
        for m in markers {
            chart
                .draw_series(DashedLineSeries::new(vec![(m.x, y0), (m.x, y1)], 6, 4, BLACK.mix(0.5).stroke_width(1)))
                .map_err(err)?;
            chart
                .draw_series(std::iter::once(Text::new(shown(&m.label), (m.x, y1 / 1.6), ("sans-serif", 13))))
                .map_err(err)?;
        }
        for (ci, comp) in comps.iter().enumerate() {
            let color = PALETTE[ci % PALETTE.len()];
            let pts: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.mode == *mode && r.compensation == *comp && finite(r.vel_err_pp_rad_s))
                .map(|r| (r.speed_cmd_rad_s, r.vel_err_pp_rad_s))
                .collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                .map_err(err)?
                .label(format!("compensation {comp}"))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 2, color.filled()))).map_err(err)?;
            let lost: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.mode == *mode && r.compensation == *comp && r.lost_sync && finite(r.vel_err_pp_rad_s))
                .map(|r| (r.speed_cmd_rad_s, r.vel_err_pp_rad_s))
                .collect();
            chart.draw_series(lost.iter().map(|&p| Cross::new(p, 6, color.stroke_width(2)))).map_err(err)?;
        }
        legend(&mut chart)?;
    }
    Ok(())
}

/// The legend every plot draws: upper right, on a light box.
pub fn legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(chart: &mut ChartContext<'a, DB, CT>) -> Result<()>
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.3))
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(|e| anyhow!("plot: {e}"))
}

#[cfg(test)]
mod tests {
    #[test]
    fn embedded_font_is_a_valid_font() {
        assert!(
            plotters::style::register_font(
                "test-font",
                plotters::style::FontStyle::Normal,
                include_bytes!("../assets/DejaVuSans.ttf")
            )
            .is_ok()
        );
    }
}
