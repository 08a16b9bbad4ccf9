//! `mrtwin paper`: the Skalski–Zalewski programme through the direct-shear and the
//! two-chamber models, with recordings, loop plots, the first-loading τ–γ curves and a
//! summary table (also as `summary.json`).

use std::fs;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use serde::Serialize;
use twin::models::{build, DirectShearParams, ModelKind, ModelParams};
use twin::stand::{run as run_stand, Programme, SimulatedSample};
use twin::EffectSet;

use crate::loops::{last_full_cycle, segment_metrics, segment_ranges, SegmentMetrics};
use crate::numbers::{positive, trim};
use crate::plot::{write_svg, Figure, Panel, Series, SeriesLabelPosition, PALETTE};
use crate::simulate::{check_finite, to_recording, write_recording};
use crate::yield_stress;

/// Shear rates \[1/s\] Skalski & Zalewski measured at 1.66, 3.33 and 5 Hz with h = 0.7 mm.
pub const PAPER_SHEAR_RATES: [f64; 3] = [73.0, 144.0, 217.0];

/// Current of the first-loading τ–γ curves (their Fig. 10) \[A\].
const FIRST_LOADING_CURRENT_A: f64 = 1.0;

/// Largest strain shown on the first-loading plot: the elastic rise and the start of
/// the plastic plateau, as in their Fig. 10 (the full quarter cycle reaches A/h ≈ 14).
const FIRST_LOADING_GAMMA_MAX: f64 = 3.0;

/// Sample rate of the first-loading runs \[Hz\]: fine enough for a smooth curve.
const FIRST_LOADING_RATE_HZ: f64 = 10_000.0;

/// Arguments of `mrtwin paper`.
#[derive(Debug, Args)]
pub struct PaperArgs {
    /// Directory for the recordings, plots and summary.json (created if needed).
    #[arg(long, value_name = "DIR", default_value = "out/paper")]
    pub out: PathBuf,
    /// Duration of each segment [s] (default: the paper's 5 s).
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    pub duration: Option<f64>,
}

/// Everything the demo reports, as written to `summary.json`.
#[derive(Debug, Serialize)]
struct Summary {
    programme: ProgrammeSummary,
    models: Vec<ModelSummary>,
    yield_stress: YieldTable,
    first_loading: Vec<FirstLoading>,
    files: Vec<String>,
}

#[derive(Debug, Serialize)]
struct ProgrammeSummary {
    amplitude_m: f64,
    #[serde(rename = "frequencies_Hz")]
    frequencies_hz: Vec<f64>,
    #[serde(rename = "currents_A")]
    currents_a: Vec<f64>,
    segment_duration_s: f64,
    #[serde(rename = "rate_Hz")]
    rate_hz: f64,
    #[serde(rename = "ambient_temperature_C")]
    ambient_temperature_c: f64,
}

#[derive(Debug, Serialize)]
struct ModelSummary {
    model: String,
    effects: String,
    csv: String,
    samples: usize,
    segments: Vec<SegmentMetrics>,
}

/// τ0 from (5.3) with n, R0 from (5.5), per current, at the paper's shear rates.
#[derive(Debug, Serialize)]
struct YieldTable {
    gap_m: f64,
    #[serde(rename = "temperature_C")]
    temperature_c: f64,
    #[serde(rename = "D0_per_s")]
    d0_per_s: f64,
    shear_rates_per_s: Vec<f64>,
    rows: Vec<YieldRow>,
}

#[derive(Debug, Serialize)]
struct YieldRow {
    #[serde(rename = "current_A")]
    current_a: f64,
    n: f64,
    #[serde(rename = "R0_Pa")]
    r0_pa: f64,
    /// One per shear rate of the table.
    #[serde(rename = "tau0_Pa")]
    tau0_pa: Vec<f64>,
}

/// The direct-shear first loading at one frequency against the (5.3) yield point.
#[derive(Debug, Serialize)]
struct FirstLoading {
    #[serde(rename = "frequency_Hz")]
    frequency_hz: f64,
    #[serde(rename = "current_A")]
    current_a: f64,
    /// Shear rate the paper measured at this frequency \[1/s\].
    paper_shear_rate_per_s: f64,
    /// (5.3) at that rate \[Pa\].
    #[serde(rename = "tau0_Pa")]
    tau0_pa: f64,
    /// Largest model stress over the quarter cycle \[Pa\].
    #[serde(rename = "model_peak_tau_Pa")]
    model_peak_tau_pa: f64,
}

/// Run the subcommand.
pub fn run(args: &PaperArgs) -> Result<()> {
    let started = Instant::now();
    let programme = programme(args.duration)?;
    let out = &args.out;
    fs::create_dir_all(out)
        .with_context(|| format!("cannot create directory {}", out.display()))?;
    let mut files = Vec::new();

    let mut models = Vec::new();
    for (kind, effects) in [
        (ModelKind::DirectShear, EffectSet::NONE),
        (ModelKind::TwoChamber, EffectSet::paper()),
    ] {
        let samples = simulate(kind, effects, &programme)?;
        let csv = out.join(format!("{kind}.csv"));
        write_recording(&csv, &to_recording(&samples, &csv))?;
        files.push(file_name(&csv));
        for (suffix, figure) in loop_figures(kind, &samples, &programme) {
            let svg = out.join(format!("{kind}-{suffix}.svg"));
            write_svg(&svg, &figure)?;
            files.push(file_name(&svg));
        }
        models.push(ModelSummary {
            model: kind.to_string(),
            effects: effects.to_string(),
            csv: file_name(&csv),
            samples: samples.len(),
            segments: segment_metrics(&samples, &programme),
        });
    }

    let ds = DirectShearParams::default();
    let temperature_c = programme.ambient_temperature_c;
    let (first_loading, figure) = first_loading(&programme, &ds)?;
    let svg = out.join("direct-shear-tau-gamma.svg");
    write_svg(&svg, &figure)?;
    files.push(file_name(&svg));

    let yield_stress = yield_table(&programme, ds.gap_height_m, temperature_c)?;
    files.push("summary.json".to_string());
    let summary = Summary {
        programme: ProgrammeSummary {
            amplitude_m: programme.segments[0].amplitude_m,
            frequencies_hz: distinct(programme.segments.iter().map(|s| s.frequency_hz)),
            currents_a: distinct(programme.segments.iter().map(|s| s.current_a)),
            segment_duration_s: programme.segments[0].duration_s,
            rate_hz: programme.rate_hz,
            ambient_temperature_c: temperature_c,
        },
        models,
        yield_stress,
        first_loading,
        files,
    };
    let json_path = out.join("summary.json");
    let json = serde_json::to_string_pretty(&summary)?;
    fs::write(&json_path, json + "\n")
        .with_context(|| format!("cannot write {}", json_path.display()))?;

    print_summary(&summary);
    println!(
        "\nwrote {} files to {} in {:.1} s",
        summary.files.len(),
        out.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The paper's programme, with the segment duration overridden if asked.
fn programme(duration: Option<f64>) -> Result<Programme> {
    let mut programme = Programme::skalski_zalewski();
    if let Some(d) = duration {
        let d = positive("--duration", d)?;
        if d * programme.rate_hz < 2.0 {
            bail!(
                "--duration {d} s gives fewer than 2 samples per segment at {} Hz",
                programme.rate_hz
            );
        }
        if d > 600.0 {
            bail!("--duration {d} s is more than the demo needs (at most 600 s per segment)");
        }
        for s in &mut programme.segments {
            s.duration_s = d;
        }
    }
    Ok(programme)
}

/// Run `kind` with default parameters through `programme`.
fn simulate(
    kind: ModelKind,
    effects: EffectSet,
    programme: &Programme,
) -> Result<Vec<SimulatedSample>> {
    let mut model = build(kind, &ModelParams::default(), effects)?;
    let samples = run_stand(model.as_mut(), programme, None);
    check_finite(&samples).with_context(|| format!("model {kind}"))?;
    Ok(samples)
}

/// The F–x and F–v figures of one model: a panel per current, a colour per frequency,
/// each the last full cycle of its segment (the whole segment if shorter).
fn loop_figures(
    kind: ModelKind,
    samples: &[SimulatedSample],
    programme: &Programme,
) -> Vec<(&'static str, Figure)> {
    let ranges = segment_ranges(samples, programme);
    let currents = distinct(programme.segments.iter().map(|s| s.current_a));
    let frequencies = distinct(programme.segments.iter().map(|s| s.frequency_hz));
    let mut fx = Figure {
        x_label: "displacement x [mm]".into(),
        y_label: "force F [N]".into(),
        panels: Vec::new(),
    };
    let mut fv = Figure {
        x_label: "velocity v [m/s]".into(),
        y_label: "force F [N]".into(),
        panels: Vec::new(),
    };
    for &current in &currents {
        let title = format!("{kind}, I = {} A", trim(current, 3));
        let mut px = Panel {
            title: title.clone(),
            ..Panel::default()
        };
        let mut pv = Panel {
            title,
            ..Panel::default()
        };
        for (seg, range) in programme.segments.iter().zip(&ranges) {
            if seg.current_a != current {
                continue;
            }
            let part = last_full_cycle(range, programme.rate_hz, seg.frequency_hz)
                .unwrap_or_else(|| range.clone());
            let part = &samples[part];
            let colour = PALETTE[frequencies
                .iter()
                .position(|&f| f == seg.frequency_hz)
                .unwrap_or(0)
                % PALETTE.len()];
            let label = format!("{} Hz", trim(seg.frequency_hz, 3));
            px.series.push(Series {
                label: label.clone(),
                colour,
                points: part
                    .iter()
                    .map(|s| (s.input.displacement_m * 1e3, s.measured_force_n))
                    .collect(),
                dashed: false,
            });
            pv.series.push(Series {
                label,
                colour,
                points: part
                    .iter()
                    .map(|s| (s.input.velocity_m_s, s.measured_force_n))
                    .collect(),
                dashed: false,
            });
        }
        fx.panels.push(px);
        fv.panels.push(pv);
    }
    vec![("fx", fx), ("fv", fv)]
}

/// The direct-shear first loading (a quarter cycle from rest) at 1 A for each frequency
/// of the programme, τ = F/A against γ = x/h, with the (5.3) yield points at the
/// paper's shear rates: the shape of Skalski & Zalewski's Fig. 10.
fn first_loading(
    programme: &Programme,
    ds: &DirectShearParams,
) -> Result<(Vec<FirstLoading>, Figure)> {
    let frequencies = distinct(programme.segments.iter().map(|s| s.frequency_hz));
    let amplitude = programme.segments[0].amplitude_m;
    let temperature_c = programme.ambient_temperature_c;
    let area = ds.shear_area_m2();
    let mut panel = Panel {
        title: format!(
            "direct-shear first loading, I = {} A, h = {} mm",
            trim(FIRST_LOADING_CURRENT_A, 3),
            trim(ds.gap_height_m * 1e3, 3)
        ),
        series: Vec::new(),
        legend: Some(SeriesLabelPosition::LowerRight),
    };
    let mut rows = Vec::new();
    for (i, &f) in frequencies.iter().enumerate() {
        let mut quarter = Programme::grid(
            amplitude,
            &[f],
            &[FIRST_LOADING_CURRENT_A],
            0.25 / f,
            FIRST_LOADING_RATE_HZ,
        );
        quarter.ambient_temperature_c = temperature_c;
        let samples = simulate(ModelKind::DirectShear, EffectSet::NONE, &quarter)?;
        let colour = PALETTE[i % PALETTE.len()];
        let points: Vec<(f64, f64)> = samples
            .iter()
            .map(|s| {
                (
                    s.input.displacement_m / ds.gap_height_m,
                    s.output.force_n / area * 1e-3,
                )
            })
            .filter(|(gamma, _)| *gamma <= FIRST_LOADING_GAMMA_MAX)
            .collect();
        let model_peak_tau_pa = samples
            .iter()
            .map(|s| s.output.force_n / area)
            .fold(f64::NEG_INFINITY, f64::max);
        panel.series.push(Series {
            label: format!("{} Hz", trim(f, 3)),
            colour,
            points,
            dashed: false,
        });
        if let Some(&rate) = PAPER_SHEAR_RATES.get(i) {
            let y = yield_stress::compute(
                FIRST_LOADING_CURRENT_A,
                temperature_c,
                ds.gap_height_m,
                rate,
            )?;
            panel.series.push(Series {
                label: format!("(5.3) at {} 1/s", trim(rate, 1)),
                colour,
                points: vec![
                    (0.0, y.tau0_pa * 1e-3),
                    (FIRST_LOADING_GAMMA_MAX, y.tau0_pa * 1e-3),
                ],
                dashed: true,
            });
            rows.push(FirstLoading {
                frequency_hz: f,
                current_a: FIRST_LOADING_CURRENT_A,
                paper_shear_rate_per_s: rate,
                tau0_pa: y.tau0_pa,
                model_peak_tau_pa,
            });
        }
    }
    let figure = Figure {
        x_label: "shear strain γ = x/h [-]".into(),
        y_label: "shear stress τ = F/A [kPa]".into(),
        panels: vec![panel],
    };
    Ok((rows, figure))
}

/// τ0 from (5.3) for each current of the programme at the paper's shear rates.
fn yield_table(programme: &Programme, gap_m: f64, temperature_c: f64) -> Result<YieldTable> {
    let rows = distinct(programme.segments.iter().map(|s| s.current_a))
        .into_iter()
        .map(|i| {
            let points = PAPER_SHEAR_RATES
                .iter()
                .map(|&rate| yield_stress::compute(i, temperature_c, gap_m, rate))
                .collect::<Result<Vec<_>>>()?;
            Ok(YieldRow {
                current_a: i,
                n: points[0].n,
                r0_pa: points[0].r0_pa,
                tau0_pa: points.iter().map(|p| p.tau0_pa).collect(),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(YieldTable {
        gap_m,
        temperature_c,
        d0_per_s: twin::fluid::BODNER_PARTOM_D0,
        shear_rates_per_s: PAPER_SHEAR_RATES.to_vec(),
        rows,
    })
}

/// The summary as readable tables on stdout.
fn print_summary(s: &Summary) {
    let p = &s.programme;
    let list = |v: &[f64]| v.iter().map(|x| trim(*x, 3)).collect::<Vec<_>>().join("/");
    println!(
        "Skalski–Zalewski programme: A = {} mm; f = {} Hz; I = {} A; {} s per segment at {} Hz",
        trim(p.amplitude_m * 1e3, 3),
        list(&p.frequencies_hz),
        list(&p.currents_a),
        trim(p.segment_duration_s, 3),
        trim(p.rate_hz, 1)
    );
    println!("(loop numbers over the last full cycle of each segment; n/a: segment shorter than a cycle)\n");
    println!(
        "{:<13} {:<32} {:>5} {:>7} {:>12} {:>13} {:>10}",
        "model", "effects", "I [A]", "f [Hz]", "peak |F| [N]", "W/cycle [J]", "z-opening"
    );
    for m in &s.models {
        for seg in &m.segments {
            println!(
                "{:<13} {:<32} {:>5} {:>7} {:>12.1} {:>13} {:>10}",
                m.model,
                m.effects,
                trim(seg.current_a, 2),
                trim(seg.frequency_hz, 2),
                seg.peak_force_n,
                or_na(seg.energy_per_cycle_j, |w| format!("{w:.2}")),
                or_na(seg.z_opening, |z| format!("{:.1} %", z * 100.0)),
            );
        }
    }

    let y = &s.yield_stress;
    println!(
        "\nYield stress τ0 [kPa], eq. (5.3) with n, R0 from (5.5); t = {} °C, h = {} mm, D0 = {:e} 1/s",
        trim(y.temperature_c, 2),
        trim(y.gap_m * 1e3, 3),
        y.d0_per_s
    );
    let header: Vec<String> = y
        .shear_rates_per_s
        .iter()
        .map(|r| format!("{:>10}", format!("{} 1/s", trim(*r, 1))))
        .collect();
    println!(
        "{:>5} {:>7} {:>10} {}",
        "I [A]",
        "n",
        "R0 [kPa]",
        header.join(" ")
    );
    for row in &y.rows {
        let taus: Vec<String> = row
            .tau0_pa
            .iter()
            .map(|t| format!("{:>10.1}", t * 1e-3))
            .collect();
        println!(
            "{:>5} {:>7.4} {:>10.1} {}",
            trim(row.current_a, 2),
            row.n,
            row.r0_pa * 1e-3,
            taus.join(" ")
        );
    }

    println!("\nDirect-shear first loading at 1 A (τ–γ curves in direct-shear-tau-gamma.svg)");
    println!(
        "{:>7} {:>12} {:>12} {:>16}",
        "f [Hz]", "rate [1/s]", "τ0 [kPa]", "model τmax [kPa]"
    );
    for r in &s.first_loading {
        println!(
            "{:>7} {:>12} {:>12.1} {:>16.1}",
            trim(r.frequency_hz, 2),
            trim(r.paper_shear_rate_per_s, 1),
            r.tau0_pa * 1e-3,
            r.model_peak_tau_pa * 1e-3
        );
    }
}

/// `f(x)` for a finite `x`, else "n/a".
fn or_na(x: f64, f: impl Fn(f64) -> String) -> String {
    if x.is_finite() {
        f(x)
    } else {
        "n/a".to_string()
    }
}

/// The distinct values of `values`, in order of first appearance.
fn distinct(values: impl Iterator<Item = f64>) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::new();
    for v in values {
        if !out.contains(&v) {
            out.push(v);
        }
    }
    out
}

fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}
