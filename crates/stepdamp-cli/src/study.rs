//! `stepdamp study`: a tolerance study (stepdamp-study) on this machine's cores. Writes the
//! results table as CSV (the Python package writes the same table as Parquet), the
//! summary as JSON, and a CDF plot of the reduction per resonance (PNG + SVG).

use crate::Global;
use crate::common::{AtomicFiles, progress};
use anyhow::{Context, Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;
use stepdamp_study::{Study, StudySummary, Table};

/// Arguments of `stepdamp study`.
#[derive(clap::Args, Debug)]
pub struct StudyArgs {
    /// The study spec (TOML: motor, variants, seed, [sweep], [plant], [controller_error],
    /// [report]; see docs/python.md).
    #[arg(long)]
    pub spec: PathBuf,
    /// Output directory: study.csv, study-summary.json, study-cdf.png, study-cdf.svg.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
}

/// Runs `stepdamp study`.
pub fn run(a: StudyArgs, g: &Global) -> Result<()> {
    let study = Study::load(&a.spec)?;
    let n = study.spec.variants;
    let mut files = AtomicFiles::in_dir_removed_on_failure(&a.out)?;
    let pb = progress(n, g.quiet, "study");
    let t0 = Instant::now();
    let table = study.run_range(0, n, &|| pb.inc(1))?;
    pb.finish_and_clear();
    let wall = t0.elapsed().as_secs_f64();
    let summary = study.summarize(&table)?;

    let csv_path = a.out.join("study.csv");
    let tmp = files.stage(&csv_path)?;
    write_table(&tmp, &table).with_context(|| format!("{}: cannot write", csv_path.display()))?;
    let json = a.out.join("study-summary.json");
    std::fs::write(files.stage(&json)?, summary.to_json())
        .with_context(|| format!("{}: cannot write", json.display()))?;
    let (png, svg) = (a.out.join("study-cdf.png"), a.out.join("study-cdf.svg"));
    let (tpng, tsvg) = (files.stage(&png)?, files.stage(&svg)?);
    cdf_plot(&table, &summary, &tsvg, &tpng)?;
    let written = files.commit()?;

    out!("{}", summary.report());
    outln!("{n} variants in {wall:.1} s wall ({:.2} variants/s)", n as f64 / wall);
    for w in written {
        outln!("wrote {}", w.display());
    }
    Ok(())
}

/// Writes the table as CSV (header = column names; `variant` as an integer).
fn write_table(path: &Path, t: &Table) -> Result<()> {
    let mut w = csv::Writer::from_path(path)?;
    w.write_record(&t.columns)?;
    for r in &t.rows {
        let mut rec: Vec<String> = r.iter().map(f64::to_string).collect();
        rec[0] = format!("{}", r[0] as u64);
        w.write_record(&rec)?;
    }
    w.flush()?;
    Ok(())
}

const PALETTE: [RGBColor; 4] =
    [RGBColor(200, 40, 40), RGBColor(30, 90, 200), RGBColor(20, 150, 60), RGBColor(150, 60, 170)];

fn cdf_plot(t: &Table, s: &StudySummary, svg: &Path, png: &Path) -> Result<()> {
    crate::plot::register_font();
    let panels = s.pairs.first().map_or(1, |p| p.resonances.len().max(1)) as u32;
    {
        let root = SVGBackend::new(svg, (420 * panels, 360)).into_drawing_area();
        draw_cdf(&root, t, s)?;
        root.present().map_err(|e| anyhow!("{}: {e}", svg.display()))?;
    }
    let root = BitMapBackend::new(png, (420 * panels, 360)).into_drawing_area();
    draw_cdf(&root, t, s)?;
    root.present().map_err(|e| anyhow!("{}: {e}", png.display()))?;
    Ok(())
}

fn draw_cdf<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, t: &Table, s: &StudySummary) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("plot: {e}");
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(&format!("{}: {} variants", s.motor, s.variants), ("sans-serif", 18)).map_err(err)?;
    let Some(first) = s.pairs.first() else { return Ok(()) };
    let panels = root.split_evenly((1, first.resonances.len().max(1)));
    for (panel, res) in panels.iter().zip(&first.resonances) {
        let k = res.order;
        let mut chart = ChartBuilder::on(panel)
            .caption(format!("k={k} ({:.2} rad/s nominal)", res.nominal_speed_rad_s), ("sans-serif", 15))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(44)
            .build_cartesian_2d((1e-2f64..1e4f64).log_scale(), 0f64..1f64)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("reduction, pp off / on")
            .y_desc("share ≤ x")
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(err)?;
        for x in [1.0, s.threshold] {
            chart
                .draw_series(DashedLineSeries::new(vec![(x, 0.0), (x, 1.0)], 5, 4, BLACK.mix(0.5).stroke_width(1)))
                .map_err(err)?;
        }
        for (pi, p) in s.pairs.iter().enumerate() {
            let name = format!("reduction_{}_{}_k{k}", p.mode, p.compensation);
            let Some(j) = t.columns.iter().position(|c| *c == name) else { continue };
            let mut x: Vec<f64> =
                t.rows.iter().map(|r| if r[j].is_nan() { 0.0 } else { r[j] }.clamp(1e-2, 1e4)).collect();
            x.sort_by(f64::total_cmp);
            let n = x.len() as f64;
            let mut pts = Vec::with_capacity(2 * x.len());
            for (i, &v) in x.iter().enumerate() {
                pts.push((v, i as f64 / n));
                pts.push((v, (i + 1) as f64 / n));
            }
            let color = PALETTE[pi % PALETTE.len()];
            chart
                .draw_series(LineSeries::new(pts, color.stroke_width(2)))
                .map_err(err)?
                .label(format!("{} {}", p.mode, p.compensation))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2)));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.3))
            .label_font(("sans-serif", 12))
            .draw()
            .map_err(err)?;
    }
    Ok(())
}
