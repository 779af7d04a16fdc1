//! The report of `--report`: spectrum, residual and validation plots.

use crate::common::AtomicFiles;
use anyhow::{Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use stepdamp_identify::fit::Fit;
use stepdamp_identify::model::Model;
use stepdamp_identify::plan::Plan;
use stepdamp_identify::refine::{Refinement, series_nm};
use stepdamp_identify::spectrum::order_spectrum;
use stepdamp_identify::validation::Validation;

pub(super) const MAX_PLOT_ORDER: usize = 16;

/// Writes `spectrum.{svg,png}` and `residual.{svg,png}` into `dir` (atomically) and
/// returns the paths. With a refinement, "after" is the feed-forward-on effort beyond the
/// feed-forward; otherwise the fit's residual.
pub(super) fn write_report(
    dir: &Path,
    f: &Fit,
    refined: Option<(&Refinement, &Plan)>,
    validation: Option<&Validation>,
    title: &str,
) -> Result<Vec<PathBuf>> {
    let mut files = AtomicFiles::in_dir(dir)?;
    let s = &f.samples;
    let before = order_spectrum(&s.theta_e_rad, &s.ripple_nm, MAX_PLOT_ORDER, 256);
    let (after, after_label) = match refined {
        Some((r, _)) => {
            let lf = &r.check.fit;
            // Effort beyond the refined feed-forward (the check run).
            let ff = &r.model;
            let beyond: Vec<f64> = lf
                .samples
                .theta_e_rad
                .iter()
                .zip(&lf.samples.ripple_nm)
                .map(|(&th, &y)| y - series_nm(ff, th))
                .collect();
            (order_spectrum(&lf.samples.theta_e_rad, &beyond, MAX_PLOT_ORDER, 256), "feed-forward on: effort beyond it")
        }
        None => (order_spectrum(&s.theta_e_rad, &s.residual_nm, MAX_PLOT_ORDER, 256), "residual of the fit"),
    };
    let spec_svg = dir.join("spectrum.svg");
    let spec_png = dir.join("spectrum.png");
    let (t1, t2) = (files.stage(&spec_svg)?, files.stage(&spec_png)?);
    let stitle = format!("{title}: effort ripple by harmonic order");
    let spectrum = Spectrum { before: &before, after: &after, after_label, title: &stitle };
    crate::plot::render(&spectrum, (1000, 600), &t1, &t2)?;
    let res_svg = dir.join("residual.svg");
    let res_png = dir.join("residual.png");
    let (t3, t4) = (files.stage(&res_svg)?, files.stage(&res_png)?);
    let model = Model::from_fit(f);
    let rtitle = format!("{title}: needed torque and residual against electrical angle");
    crate::plot::render(&Residual { fit: f, model: &model, title: &rtitle }, (1000, 700), &t3, &t4)?;
    if let Some(validation) = validation {
        let (svg, png) = (dir.join("validation.svg"), dir.join("validation.png"));
        let (t5, t6) = (files.stage(&svg)?, files.stage(&png)?);
        let vtitle = format!("{title}: effort ripple the model leaves unexplained, per run");
        crate::plot::render(&crate::plot::ValidationFigure { validation, title: &vtitle }, (1000, 600), &t5, &t6)?;
    }
    files.commit()
}

struct Spectrum<'a> {
    before: &'a [f64],
    after: &'a [f64],
    after_label: &'a str,
    title: &'a str,
}

impl crate::plot::Figure for Spectrum<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        draw_spectrum(root, self.before, self.after, self.after_label, self.title)
    }
}

struct Residual<'a> {
    fit: &'a Fit,
    model: &'a Model,
    title: &'a str,
}

impl crate::plot::Figure for Residual<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        draw_residual(root, self.fit, self.model, self.title)
    }
}

pub(super) fn draw_spectrum<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    before: &[f64],
    after: &[f64],
    after_label: &str,
    title: &str,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("plot: {e}");
    root.fill(&WHITE).map_err(err)?;
    let to_mnm = |v: &[f64]| v.iter().skip(1).map(|x| 1e3 * x).collect::<Vec<f64>>();
    let (b, a) = (to_mnm(before), to_mnm(after));
    let finite = || b.iter().chain(&a).copied().filter(|v| v.is_finite() && *v > 0.0);
    let top = finite().fold(1e-6, f64::max) * 2.0;
    // Log scale: the ripple left after refinement is orders of magnitude below the detent.
    let floor = finite().fold(top, f64::min).max(top * 1e-5) / 2.0;
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 20))
        .margin(14)
        .x_label_area_size(40)
        .y_label_area_size(80)
        .build_cartesian_2d(0.5f64..(MAX_PLOT_ORDER as f64 + 0.5), (floor..top).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("harmonic order k of the electrical angle")
        .y_desc("amplitude (mN·m)")
        .x_labels(MAX_PLOT_ORDER)
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_label_formatter(&|y| format!("{y:.1e}"))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    let red = RGBColor(200, 40, 40);
    let blue = RGBColor(30, 90, 200);
    let bar = |k: f64, v: f64, left: bool| {
        let (x0, x1) = if left { (k - 0.38, k - 0.02) } else { (k + 0.02, k + 0.38) };
        (x0, x1, v.max(floor))
    };
    chart
        .draw_series(b.iter().enumerate().map(|(i, &v)| {
            let (x0, x1, y) = bar((i + 1) as f64, v, true);
            Rectangle::new([(x0, floor), (x1, y)], red.filled())
        }))
        .map_err(err)?
        .label("feed-forward off: needed torque minus friction")
        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], red.filled()));
    chart
        .draw_series(a.iter().enumerate().map(|(i, &v)| {
            let (x0, x1, y) = bar((i + 1) as f64, v, false);
            Rectangle::new([(x0, floor), (x1, y)], blue.filled())
        }))
        .map_err(err)?
        .label(after_label.to_string())
        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], blue.filled()));
    crate::plot::legend(&mut chart)?;
    Ok(())
}

pub(super) fn draw_residual<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    f: &Fit,
    model: &Model,
    title: &str,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("plot: {e}");
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, ("sans-serif", 20)).map_err(err)?;
    let panels = root.split_evenly((2, 1));
    let s = &f.samples;
    let n = s.theta_e_rad.len();
    let step = (n / 4000).max(1);
    let idx: Vec<usize> = (0..n).step_by(step).collect();
    let tau = std::f64::consts::TAU;
    for (pi, panel) in panels.iter().enumerate() {
        let (vals, caption): (Vec<(f64, f64)>, &str) = if pi == 0 {
            (
                idx.iter().map(|&i| (s.theta_e_rad[i], 1e3 * s.ripple_nm[i])).collect(),
                "needed torque minus friction (points) and the identified detent series (line)",
            )
        } else {
            (idx.iter().map(|&i| (s.theta_e_rad[i], 1e3 * s.residual_nm[i])).collect(), "residual of the fit")
        };
        let lim = vals.iter().map(|p| p.1.abs()).filter(|v| v.is_finite()).fold(1e-6, f64::max) * 1.05;
        let mut chart = ChartBuilder::on(panel)
            .caption(caption, ("sans-serif", 15))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..tau, -lim..lim)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("electrical angle Nr·θ_fb (rad)")
            .y_desc("mN·m")
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(err)?;
        let c = if pi == 0 { RGBColor(200, 40, 40) } else { RGBColor(30, 90, 200) };
        chart.draw_series(vals.iter().map(|&p| Circle::new(p, 1, c.mix(0.35).filled()))).map_err(err)?;
        if pi == 0 {
            let line: Vec<(f64, f64)> =
                (0..=400).map(|i| tau * i as f64 / 400.0).map(|t| (t, 1e3 * series_nm(model, t))).collect();
            chart.draw_series(LineSeries::new(line, BLACK.stroke_width(2))).map_err(err)?;
        }
    }
    Ok(())
}
