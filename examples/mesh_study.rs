//! Error per element, uniform against adaptive meshing, on `builtin:penumbra` (a square
//! emitter, a floating occluder, a floor; exact answer by polygon clipping, see
//! `radiosity::analytic`).
//!
//! `cargo run --release --example mesh_study -- OUT_DIR` writes `OUT_DIR/mesh_study.csv`
//! (mesh, setting, elements, RMS and max relative error of the floor's radiosity at a 41×41
//! grid of points, Gouraud reconstruction as the viewer shows it) and `mesh_study.png`.

use plotters::prelude::*;
use radiosity::analytic::{penumbra_errors, solve_penumbra};
use radiosity::mesh::{AdaptiveSettings, Reconstruction};

/// (elements, RMS relative error, max relative error) for Gouraud and for Hermite.
fn run(element_size: f64, adaptive: Option<AdaptiveSettings>) -> (usize, [(f64, f64); 2]) {
    let s = solve_penumbra(element_size, adaptive);
    let mut floor = 0;
    let errors = [Reconstruction::Gouraud, Reconstruction::Hermite].map(|mode| {
        let (rms, max, n) = penumbra_errors(&s, mode);
        floor = n;
        (rms, max)
    });
    (floor, errors)
}

fn main() {
    let out = std::path::PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| ".".into()));
    std::fs::create_dir_all(&out).expect("output folder");
    let mut rows: Vec<(String, String, usize, f64, f64)> = Vec::new();
    for size in [0.2, 0.14, 0.1, 0.07, 0.05, 0.035, 0.025, 0.0175] {
        let (n, e) = run(size, None);
        for (name, (rms, max)) in ["uniform Gouraud", "uniform Hermite"].iter().zip(e) {
            println!("{name:<17} size {size:<7} {n:>7} floor elements  RMS {rms:.4}  max {max:.4}");
            rows.push((name.to_string(), format!("size {size}"), n, rms, max));
        }
    }
    // The minimum size goes down with the threshold (sizes halve from the 0.2 m start,
    // so the minimum is one of 0.025, 0.0125, 0.00625 m), so neither bound alone stops
    // the refinement.
    let list: [(f32, f64); 5] = [
        (0.4, 0.025),
        (0.3, 0.025),
        (0.2, 0.0125),
        (0.14, 0.0125),
        (0.1, 0.00625),
    ];
    for (threshold, min) in list {
        let a = AdaptiveSettings {
            threshold,
            min_size: Some(min),
            max_passes: 8,
            max_elements: 2_000_000,
        };
        let (n, e) = run(0.2, Some(a));
        for (name, (rms, max)) in ["adaptive Gouraud", "adaptive Hermite"].iter().zip(e) {
            println!(
                "{name:<17} threshold {threshold:<5} min {min:<7} {n:>7} floor elements  RMS {rms:.4}  max {max:.4}"
            );
            rows.push((
                name.to_string(),
                format!("threshold {threshold} min {min}"),
                n,
                rms,
                max,
            ));
        }
    }
    // Uniform elements for the same error: log-log interpolation along the uniform curve
    // of the same reconstruction; the ratio to the adaptive count is the saving.
    let uniform_equivalent = |mode: &str, rms: f64| -> Option<f64> {
        let curve: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.0 == format!("uniform {mode}"))
            .map(|r| (r.2 as f64, r.3))
            .collect();
        curve.windows(2).find_map(|w| {
            let ((n0, e0), (n1, e1)) = (w[0], w[1]);
            (rms <= e0 && rms >= e1).then(|| {
                let t = (rms.ln() - e0.ln()) / (e1.ln() - e0.ln());
                (n0.ln() + t * (n1.ln() - n0.ln())).exp()
            })
        })
    };
    let mut csv = String::from(
        "mesh,setting,elements,rms_relative,max_relative,uniform_elements_same_rms,saving\n",
    );
    for (m, s, n, r, x) in &rows {
        let (eq, saving) = match m.strip_prefix("adaptive ") {
            Some(mode) => match uniform_equivalent(mode, *r) {
                Some(u) => {
                    println!(
                        "{m:<17} {s:<28} {n:>6} elements: uniform needs {u:>7.0} ({:.2}×)",
                        u / *n as f64
                    );
                    (format!("{u:.0}"), format!("{:.2}", u / *n as f64))
                }
                None => (String::new(), String::new()),
            },
            None => (String::new(), String::new()),
        };
        csv += &format!("{m},{s},{n},{r},{x},{eq},{saving}\n");
    }
    std::fs::write(out.join("mesh_study.csv"), csv).expect("csv");

    let path = out.join("mesh_study.png");
    radiosity::cli::register_font();
    let (w, h) = (800u32, 560u32);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).expect("plot");
        let xs: Vec<f64> = rows.iter().map(|r| r.2 as f64).collect();
        let ys: Vec<f64> = rows.iter().map(|r| r.3).collect();
        let (x0, x1) = (
            xs.iter().copied().fold(f64::INFINITY, f64::min) * 0.7,
            xs.iter().copied().fold(0.0, f64::max) * 1.4,
        );
        let (y0, y1) = (
            ys.iter().copied().fold(f64::INFINITY, f64::min) * 0.7,
            ys.iter().copied().fold(0.0, f64::max) * 1.4,
        );
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "builtin:penumbra: floor radiosity error against elements",
                ("sans-serif", 20),
            )
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .expect("plot");
        chart
            .configure_mesh()
            .x_desc("floor elements")
            .y_desc("RMS relative error")
            .draw()
            .expect("plot");
        for (name, colour) in [
            ("uniform Gouraud", BLUE),
            ("adaptive Gouraud", RED),
            ("uniform Hermite", CYAN),
            ("adaptive Hermite", MAGENTA),
        ] {
            let pts: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.0 == name)
                .map(|r| (r.2 as f64, r.3))
                .collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(2)))
                .expect("plot")
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
            chart
                .draw_series(pts.iter().map(|p| Circle::new(*p, 4, colour.filled())))
                .expect("plot");
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .expect("plot");
        root.present().expect("plot");
    }
    image::RgbImage::from_raw(w, h, buf)
        .expect("plot buffer")
        .save(&path)
        .expect("png");
    println!("wrote {}", path.display());
}
