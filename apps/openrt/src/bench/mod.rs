//! `openrt bench`: the paper's frame-rate table on this machine, speed
//! against error, and the component figures, written to docs/BENCHMARKS.md.
//! Three steps: `measure` runs the scenes and returns typed `results`;
//! `report` renders them, judging each goal of `goals`; `run` writes the
//! report atomically.

mod goals;
mod measure;
mod report;
mod results;

use std::path::{Path, PathBuf};
use std::time::Instant;

use results::Quality;

/// Options of a benchmark run.
pub struct BenchOptions {
    pub scenes: Vec<String>,
    pub frames: usize,
    pub width: u32,
    pub height: u32,
    pub threads: Vec<usize>,
    /// Triangles of the skinned glTF figures whose per-frame cost is measured.
    pub deform_sizes: Vec<usize>,
    pub out: PathBuf,
    pub command: String,
    /// A run on a larger machine (`--device`): the frame rates of the
    /// default backend over kd-trees and BVHs and of Embree's packets at
    /// every thread count, the paper's table and the thread scaling, and
    /// nothing measured on one thread only (those sections are in
    /// docs/BENCHMARKS.md).
    pub device: bool,
}

/// Runs every measurement and writes the report (and its plot and images).
pub fn run(o: &BenchOptions) -> Result<(), String> {
    let start = Instant::now();
    let results = measure::all(o)?;
    if o.device {
        let md = report::render_device(o, &results, start.elapsed().as_secs_f64());
        openrt_core::write_atomically(&o.out, |w| w.write_all(md.as_bytes())).map_err(|e| e.to_string())?;
        eprintln!("bench: wrote {}", o.out.display());
        return Ok(());
    }
    let svg = o.out.with_file_name("bench-speed-error.svg");
    let quality: Vec<&Quality> = results.quality.iter().flat_map(|q| &q.rows).collect();
    let plotted = plot(&svg, &quality).map(|()| "bench-speed-error.svg".to_string());
    let md = report::render(o, &results, &plotted, start.elapsed().as_secs_f64());
    openrt_core::write_atomically(&o.out, |w| w.write_all(md.as_bytes())).map_err(|e| e.to_string())?;
    eprintln!("bench: wrote {} and {}", o.out.display(), svg.display());
    Ok(())
}

/// Registers DejaVu Sans as the plots' "sans-serif" font.
pub(crate) fn register_plot_font() -> Result<(), String> {
    use plotters::prelude::FontStyle;
    let font = ["/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf"]
        .iter()
        .find_map(|p| std::fs::read(p).ok())
        .ok_or("no DejaVuSans.ttf for the plot's labels (apt-get install fonts-dejavu-core)")?;
    plotters::style::register_font("sans-serif", FontStyle::Normal, Box::leak(font.into_boxed_slice()))
        .map_err(|_| "cannot load the plot font".to_string())
}

fn plot(path: &Path, q: &[&Quality]) -> Result<(), String> {
    use plotters::prelude::*;
    register_plot_font()?;
    let root = SVGBackend::new(path, (720, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let max_ms = q.iter().map(|x| x.ms).fold(1.0, f64::max) * 1.15;
    let max_err = q.iter().map(|x| x.rmse).fold(0.01, f64::max) * 1.15;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "frame time against error (RMSE vs a 64-spp depth-8 reference)",
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..max_ms, 0.0..max_err)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc("render time per frame (ms)")
        .y_desc("RMSE")
        .draw()
        .map_err(|e| e.to_string())?;
    chart
        .draw_series(q.iter().map(|x| {
            EmptyElement::at((x.ms, x.rmse))
                + Circle::new((0, 0), 4, BLUE.filled())
                + Text::new(format!("{}: {}", x.scene, x.label), (6, -6), ("sans-serif", 10))
        }))
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::measure::{median, rmse_psnr, upsample};
    use glam::Vec3;
    use openrt_core::Image;

    #[test]
    fn error_metrics_and_upsampling() {
        let a = Image {
            width: 2,
            height: 1,
            pixels: vec![Vec3::ZERO, Vec3::ONE],
        };
        assert_eq!(rmse_psnr(&a, &a).0, 0.0);
        let b = Image {
            width: 2,
            height: 1,
            pixels: vec![Vec3::ONE, Vec3::ONE],
        };
        let (rmse, psnr) = rmse_psnr(&a, &b);
        assert!((rmse - 0.5f64.sqrt()).abs() < 1e-9 && (psnr - 3.0103).abs() < 1e-3);
        let u = upsample(&a, 4, 2);
        assert_eq!(
            u.pixels,
            vec![
                Vec3::ZERO,
                Vec3::ZERO,
                Vec3::ONE,
                Vec3::ONE,
                Vec3::ZERO,
                Vec3::ZERO,
                Vec3::ONE,
                Vec3::ONE
            ]
        );
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
    }
}
