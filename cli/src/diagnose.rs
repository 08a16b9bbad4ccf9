//! `mrtwin diagnose`: find the physics the baseline damper model leaves out, add it, and
//! show the fit improve on held-out data (the `diagnose` crate does the work; this module
//! reads the input and writes the JSON, the Markdown report and the SVG plots).

use std::fs;
use std::path::{Path, PathBuf};

use ::diagnose::data::Prepared;
use ::diagnose::report::render_markdown;
use ::diagnose::{Diagnosis, Options, Progress, Selector, Signals};
use anyhow::{bail, Context, Result};
use bridge::csv::Recording;
use clap::Args;

use crate::html::{report_page, InlineFigure};
use crate::output::write_whole;
use crate::plot::{svg_string, write_svg, Figure, Panel, Series, PALETTE};

/// The baselines `--baseline` accepts.
pub const BASELINES: [&str; 1] = ["bingham-flow"];

/// Arguments of `mrtwin diagnose`.
#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// A CSV recording in the format of PHYSICS.md (several segments may follow each other).
    #[arg(value_name = "INPUT")]
    pub input: PathBuf,
    /// Baseline model: `bingham-flow`, the incompressible Bingham flow-mode damper with yield
    /// force and viscous coefficient free at each current level.
    #[arg(long, value_name = "MODEL", default_value = "bingham-flow")]
    pub baseline: String,
    /// Write the diagnosis as JSON here.
    #[arg(long, value_name = "OUT.json")]
    pub json: Option<PathBuf>,
    /// Write SVG plots into this directory (created if missing).
    #[arg(long, value_name = "DIR")]
    pub plots: Option<PathBuf>,
    /// Write the Markdown report here (it is printed to stdout otherwise).
    #[arg(long, value_name = "OUT.md")]
    pub report: Option<PathBuf>,
    /// Write the report and its plots as one self-contained HTML page here (plots inline
    /// as SVG, nothing referenced from outside the file).
    #[arg(long, value_name = "OUT.html")]
    pub html: Option<PathBuf>,
    /// Write the per-sample comparison as CSV here: time, rebuilt velocity and its σ,
    /// current, measured force, the baseline's and the final model's force, the sample's
    /// weight and its role (`fit`, `held_out`, `unscored` — in a held-out block at a current the
    /// fit cannot predict or faster than the fit reaches there — or `excluded`).
    #[arg(long, value_name = "OUT.csv")]
    pub residuals: Option<PathBuf>,
    /// How candidate effects are accepted: `calibrated` (against a bootstrap null of the
    /// fitted model at a 2 % family-wise false-alarm rate), `rules` (the four hand-set
    /// rules of the first version) or `sindy` (SINDy-style sparse regression, for
    /// comparison).
    #[arg(long, value_name = "NAME", default_value = "calibrated", value_parser = parse_selector)]
    pub selector: Selector,
    /// How the yield force is interpolated in current between the knots of a record whose
    /// current varies continuously: `lines` (straight lines), `cubic` (a cubic Hermite
    /// curve through the knots) or `auto` (the baseline settled on both, the one that fits
    /// the fitting blocks better kept). Held levels are always joined by lines.
    /// docs/diagnose.md §2 compares them on the proving ground.
    #[arg(long, value_name = "CURVE", default_value = "auto", value_parser = parse_yield_curve)]
    pub yield_curve: ::diagnose::YieldCurve,
    /// Bootstrap replicates per selection round (`calibrated`).
    #[arg(long, value_name = "N", default_value_t = ::diagnose::Calibration::default().replicates)]
    pub replicates: usize,
    /// Family-wise false-alarm rate per record (`calibrated`).
    #[arg(long, value_name = "ALPHA", default_value_t = ::diagnose::Calibration::default().family_alpha)]
    pub family_alpha: f64,
    /// The least held-out gain a finding needs (`calibrated`): the fall of the held-out
    /// mean square, in units of the record's force-noise variance σ_F². 0 reports every
    /// effect the bootstrap accepts, however little it changes the prediction.
    #[arg(long, value_name = "X", default_value_t = ::diagnose::Calibration::default().min_holdout_gain_noise)]
    pub min_holdout_gain: f64,
    /// The twin to diagnose (parameter file, section `mrtwin_twin`, as `mrtwin fit` writes):
    /// its effects are part of the baseline and the candidates are the effects it lacks.
    /// The JSON gains a `twin` entry with the twin's replay residual on the recording.
    #[arg(long, value_name = "TWIN.yaml")]
    pub params: Option<PathBuf>,
    /// With `--params`: write the twin with the effects found switched on and calibrated
    /// on the recording (the twin unchanged when nothing is found).
    #[arg(long, value_name = "UPGRADED.yaml", requires = "params")]
    pub write_params: Option<PathBuf>,
}

fn parse_selector(s: &str) -> Result<Selector, String> {
    Selector::parse(s).ok_or_else(|| {
        format!("unknown selector '{s}' (expected one of: calibrated, rules, sindy)")
    })
}

fn parse_yield_curve(s: &str) -> Result<::diagnose::YieldCurve, String> {
    ::diagnose::YieldCurve::parse(s)
        .ok_or_else(|| format!("unknown yield curve '{s}' (expected one of: lines, cubic, auto)"))
}

/// A one-line progress bar on stderr, drawn only when stderr is a terminal.
fn progress_bar(p: Progress) {
    use std::io::{IsTerminal, Write};
    let mut err = std::io::stderr();
    if !err.is_terminal() {
        return;
    }
    let width = 30usize;
    let filled = (width * p.done)
        .checked_div(p.total)
        .map_or(width, |f| f.min(width));
    let _ = write!(
        err,
        "\r\x1b[2K  round {} {:<20} [{}{}] {}/{}",
        p.round,
        p.stage,
        "#".repeat(filled),
        ".".repeat(width - filled),
        p.done,
        p.total
    );
    let _ = err.flush();
}

/// Read the recording to diagnose.
/// A CSV recording or a bag (directory or .mcap), see [`bridge::open_recording`].
pub fn load_input(path: &Path) -> Result<Recording> {
    bridge::open_recording(path)
        .with_context(|| format!("cannot use {} as a recording", path.display()))
}

fn signals(rec: &Recording) -> Signals {
    let s = &rec.samples;
    Signals {
        time_s: s.iter().map(|x| x.time_s).collect(),
        displacement_m: s.iter().map(|x| x.displacement_m).collect(),
        velocity_m_s: s.iter().map(|x| x.velocity_m_s).collect(),
        force_n: s.iter().map(|x| x.force_n).collect(),
        current_a: s.iter().map(|x| x.current_a).collect(),
        velocity_derived: rec.velocity_derived,
    }
}

/// Run the diagnosis.
pub fn run(args: &DiagnoseArgs) -> Result<()> {
    if !BASELINES.contains(&args.baseline.as_str()) {
        bail!(
            "unknown baseline '{}' (expected one of: {})",
            args.baseline,
            BASELINES.join(", ")
        );
    }
    let rec = load_input(&args.input)?;
    let name = args.input.display().to_string();
    if !(args.family_alpha > 0.0 && args.family_alpha < 1.0) {
        bail!(
            "--family-alpha {} is not a rate in (0, 1)",
            args.family_alpha
        );
    }
    if !(args.min_holdout_gain.is_finite() && args.min_holdout_gain >= 0.0) {
        bail!(
            "--min-holdout-gain {} must be a number ≥ 0 (units of σ_F²)",
            args.min_holdout_gain
        );
    }
    if args.replicates < 8 {
        bail!(
            "--replicates {}: the calibration needs at least 8",
            args.replicates
        );
    }
    let twin = match &args.params {
        Some(p) => Some((p, crate::fit::base_params(Some(p), None, None)?)),
        None => None,
    };
    let base_effects = twin.as_ref().map_or_else(Vec::new, |(_, t)| {
        t.model.effects(t.effects).iter().collect::<Vec<_>>()
    });
    let opts = Options {
        base_effects,
        selector: args.selector,
        yield_curve: args.yield_curve,
        calibration: ::diagnose::Calibration {
            replicates: args.replicates,
            family_alpha: args.family_alpha,
            min_holdout_gain_noise: args.min_holdout_gain,
            ..Default::default()
        },
        ..Default::default()
    };
    let dg = ::diagnose::diagnose_with_progress(&signals(&rec), &name, &opts, &progress_bar)
        .with_context(|| format!("cannot diagnose {name}"))?;
    {
        use std::io::IsTerminal;
        if std::io::stderr().is_terminal() {
            eprint!("\r\x1b[2K");
        }
    }
    let md = render_markdown(&dg.report);
    let twin_check = match &twin {
        Some((path, t)) => Some(crate::upgrade::write_upgraded(
            t,
            path,
            &dg,
            &[crate::fit::sensor_samples(&rec)],
            &args.input,
            args.write_params.as_deref(),
        )?),
        None => None,
    };
    if let Some(path) = &args.json {
        let mut value = serde_json::to_value(&dg.report).context("cannot encode JSON")?;
        if let Some(check) = &twin_check {
            value["twin"] = check.json.clone();
        }
        let text = serde_json::to_string_pretty(&value).context("cannot encode JSON")?;
        fs::write(path, text + "\n").with_context(|| format!("cannot write {}", path.display()))?;
    }
    if let Some(dir) = &args.plots {
        fs::create_dir_all(dir)
            .with_context(|| format!("cannot create plot directory {}", dir.display()))?;
        for f in figures(&dg) {
            write_svg(&dir.join(format!("{}.svg", f.stem)), &f.figure)?;
        }
    }
    if let Some(path) = &args.html {
        write_html(path, &name, &md, &dg)?;
    }
    if let Some(path) = &args.residuals {
        write_whole(path, residuals_csv(&dg).as_bytes())?;
    }
    match &args.report {
        Some(path) => {
            fs::write(path, &md).with_context(|| format!("cannot write {}", path.display()))?;
            let found = dg.found();
            println!(
                "{}: {}; held-out RMS {:.2} N (baseline) → {:.2} N (final); report {}",
                name,
                match (found.is_empty(), dg.report.unexplained.len()) {
                    (true, 0) => "no effect found, residual at noise level".to_string(),
                    (true, k) => format!("no effect found, {k} unexplained structure(s)"),
                    (false, 0) => format!("found {}", found.join(", ")),
                    (false, k) => {
                        format!("found {}; {k} unexplained structure(s)", found.join(", "))
                    }
                },
                dg.report.baseline.holdout_rmse_n,
                dg.report.final_model.holdout_rmse_n,
                path.display()
            );
        }
        None => print!("{md}"),
    }
    if let Some(line) = twin_check.and_then(|c| c.summary) {
        println!("{line}");
    }
    Ok(())
}

/// The per-sample comparison of `--residuals`.
fn residuals_csv(dg: &Diagnosis) -> String {
    use std::fmt::Write;
    let d = &dg.data;
    let mut out = String::from(
        "time_s,velocity_m_s,velocity_sigma_m_s,current_A,force_N,baseline_N,final_N,weight,role\n",
    );
    for j in 0..d.len() {
        let role = if d.excluded[j] {
            "excluded"
        } else if d.holdout[j] {
            "held_out"
        } else if d.train[j] {
            "fit"
        } else {
            // In a held-out block but not scored: at a current beyond the fitted levels,
            // at a level the fit never saw, or faster than the fitting samples reach at
            // its current knot (`split.method`).
            "unscored"
        };
        let _ = writeln!(
            out,
            "{},{:.9e},{:.4e},{},{},{:.9e},{:.9e},{:.9e},{}",
            d.t[j],
            d.v[j],
            d.v_sigma[j],
            d.i[j],
            d.f[j],
            dg.baseline_force[j],
            dg.final_force[j],
            d.weight[j],
            role
        );
    }
    out
}

/// Up to three held-out strokes at distinct current levels (lowest, middle, highest), each
/// the one where the baseline misses most.
fn chosen_strokes(d: &Prepared, base: &[f64]) -> Vec<(f64, Vec<usize>)> {
    let nk = d.knots.len();
    let picks: Vec<usize> = match nk {
        1 => vec![0],
        2 => vec![0, 1],
        _ => vec![0, nk / 2, nk - 1],
    };
    let nearest = |i: f64| {
        (0..nk)
            .min_by(|&a, &b| (d.knots[a] - i).abs().total_cmp(&(d.knots[b] - i).abs()))
            .unwrap_or(0)
    };
    let mut strokes: Vec<Vec<usize>> = vec![Vec::new(); d.cycles];
    for j in 0..d.len() {
        if d.holdout[j] {
            strokes[d.cycle[j]].push(j);
        }
    }
    let mut out = Vec::new();
    for k in picks {
        let best = strokes
            .iter()
            .filter(|s| s.len() > 8 && s.iter().all(|&j| nearest(d.i[j]) == k))
            .max_by(|a, b| {
                let e = |s: &Vec<usize>| s.iter().map(|&j| (d.f[j] - base[j]).powi(2)).sum::<f64>();
                e(a).total_cmp(&e(b))
            });
        if let Some(s) = best {
            out.push((d.knots[k], s.clone()));
        }
    }
    out
}

/// Loops averaged by bin, for any excitation (broadband strokes, currents switched within
/// strokes): the held-out samples of each current band (lower, middle and upper third of
/// the current range) are binned by `x_of` (24 bins) separately for increasing and
/// decreasing `x_of` (so the loop keeps its opening), and the mean measured, baseline and
/// final force of each bin drawn as one closed path.
fn binned_panels(
    dg: &Diagnosis,
    x_of: &dyn Fn(usize) -> f64,
    rising: &dyn Fn(usize) -> bool,
) -> Vec<Panel> {
    let d = &dg.data;
    let held: Vec<usize> = (0..d.len()).filter(|&j| d.holdout[j]).collect();
    if held.is_empty() {
        return Vec::new();
    }
    let (ilo, ihi) = held
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &j| {
            (a.min(d.i[j]), b.max(d.i[j]))
        });
    let bands = if ihi - ilo > 1e-6 { 3 } else { 1 };
    let band_of = |i: f64| {
        if bands == 1 {
            0
        } else {
            (((i - ilo) / (ihi - ilo) * 3.0) as usize).min(2)
        }
    };
    const BINS: usize = 24;
    let mut panels = Vec::new();
    for b in 0..bands {
        let sel: Vec<usize> = held
            .iter()
            .copied()
            .filter(|&j| band_of(d.i[j]) == b)
            .collect();
        if sel.len() < 4 * BINS {
            continue;
        }
        let (xlo, xhi) = sel
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, c), &j| {
                (a.min(x_of(j)), c.max(x_of(j)))
            });
        let width = ((xhi - xlo) / BINS as f64).max(1e-12);
        let path = |y: &dyn Fn(usize) -> f64| {
            let mut acc = vec![[(0.0, 0.0, 0usize); BINS]; 2];
            for &j in &sel {
                let k = (((x_of(j) - xlo) / width) as usize).min(BINS - 1);
                let a = &mut acc[usize::from(!rising(j))][k];
                a.0 += x_of(j);
                a.1 += y(j);
                a.2 += 1;
            }
            let mut pts: Vec<(f64, f64)> = acc[0]
                .iter()
                .filter(|a| a.2 >= 3)
                .map(|a| (a.0 / a.2 as f64, a.1 / a.2 as f64))
                .collect();
            pts.extend(
                acc[1]
                    .iter()
                    .rev()
                    .filter(|a| a.2 >= 3)
                    .map(|a| (a.0 / a.2 as f64, a.1 / a.2 as f64)),
            );
            if let Some(&p) = pts.first() {
                pts.push(p);
            }
            pts
        };
        let lo_i = sel.iter().map(|&j| d.i[j]).fold(f64::INFINITY, f64::min);
        let hi_i = sel
            .iter()
            .map(|&j| d.i[j])
            .fold(f64::NEG_INFINITY, f64::max);
        panels.push(Panel {
            title: format!("held-out, {lo_i:.2}–{hi_i:.2} A, mean per bin"),
            series: vec![
                Series {
                    label: "measured".into(),
                    colour: PALETTE[0],
                    points: path(&|j| d.f[j]),
                    dashed: false,
                },
                Series {
                    label: "baseline".into(),
                    colour: PALETTE[1],
                    points: path(&|j| dg.baseline_force[j]),
                    dashed: true,
                },
                Series {
                    label: "final model".into(),
                    colour: PALETTE[2],
                    points: path(&|j| dg.final_force[j]),
                    dashed: false,
                },
            ],
            legend: None,
        });
    }
    panels
}

fn loop_figure(
    dg: &Diagnosis,
    x_of: impl Fn(usize) -> f64,
    rising: impl Fn(usize) -> bool,
    x_label: &str,
) -> Figure {
    let d = &dg.data;
    let strokes = if d.held_levels {
        chosen_strokes(d, &dg.baseline_force)
    } else {
        Vec::new()
    };
    if strokes.is_empty() {
        return Figure {
            x_label: x_label.into(),
            y_label: "force (N)".into(),
            panels: binned_panels(dg, &x_of, &rising),
        };
    }
    let panels = strokes
        .into_iter()
        .map(|(i, s)| Panel {
            title: format!("held-out stroke at {i:.2} A"),
            series: vec![
                Series {
                    label: "measured".into(),
                    colour: PALETTE[0],
                    points: s.iter().map(|&j| (x_of(j), d.f[j])).collect(),
                    dashed: false,
                },
                Series {
                    label: "baseline".into(),
                    colour: PALETTE[1],
                    points: s.iter().map(|&j| (x_of(j), dg.baseline_force[j])).collect(),
                    dashed: true,
                },
                Series {
                    label: "final model".into(),
                    colour: PALETTE[2],
                    points: s.iter().map(|&j| (x_of(j), dg.final_force[j])).collect(),
                    dashed: false,
                },
            ],
            legend: None,
        })
        .collect();
    Figure {
        x_label: x_label.into(),
        y_label: "force (N)".into(),
        panels,
    }
}

/// A plot of the diagnosis: its file stem (`--plots`), caption (`--html`) and figure.
struct NamedFigure {
    stem: &'static str,
    caption: &'static str,
    figure: Figure,
}

/// The plots of a diagnosis: the F–v and F–x loops, the residual by stroke phase, and the
/// residual over time when a time-dependent effect is found or undecided.
fn figures(dg: &Diagnosis) -> Vec<NamedFigure> {
    let d = &dg.data;
    let mut out = vec![
        NamedFigure {
            stem: "loops_force_velocity",
            caption: "Force against velocity on held-out strokes: measured, baseline and final \
                      model",
            figure: loop_figure(dg, |j| d.v[j], |j| d.a[j] >= 0.0, "velocity (m/s)"),
        },
        NamedFigure {
            stem: "loops_force_displacement",
            caption: "Force against displacement on the same strokes",
            figure: loop_figure(dg, |j| 1e3 * d.x[j], |j| d.v[j] >= 0.0, "displacement (mm)"),
        },
    ];
    // Residual by stroke phase: 1 near reversal, 2 accelerating, 3 decelerating,
    // 4 compression, 5 rebound.
    let rp = &dg.report.residual_by_phase;
    let series = |label: &str, c, f: &dyn Fn(usize) -> f64| Series {
        label: label.into(),
        colour: c,
        points: (0..rp.len()).map(|k| ((k + 1) as f64, f(k))).collect(),
        dashed: false,
    };
    out.push(NamedFigure {
        stem: "residual_by_phase",
        caption: "Held-out RMS residual by stroke phase, baseline and final model",
        figure: Figure {
            x_label: "1 near reversal, 2 accelerating, 3 decelerating, 4 compression, 5 rebound"
                .into(),
            y_label: "RMS residual (N)".into(),
            panels: vec![Panel {
                title: "residual by stroke phase".into(),
                series: vec![
                    series("baseline", PALETTE[1], &|k| rp[k].baseline_rms_n),
                    series("final model", PALETTE[2], &|k| rp[k].final_rms_n),
                ],
                legend: None,
            }],
        },
    });
    let time_effects = ["thermal_softening", "field_lag"];
    let involved = dg
        .report
        .findings
        .iter()
        .map(|f| f.effect.as_str())
        .chain(
            dg.report
                .undecided
                .iter()
                .flat_map(|u| u.effects.iter().map(|s| s.as_str())),
        )
        .any(|e| time_effects.contains(&e));
    if involved {
        out.push(NamedFigure {
            stem: "residual_over_time",
            caption: "Residual over time (1 s RMS windows) and after current steps",
            figure: time_figure(dg),
        });
    }
    out
}

/// Write the report `md` of `dg` and its plots as one HTML page at `path`, whole or not
/// at all ([`write_whole`]).
fn write_html(path: &Path, name: &str, md: &str, dg: &Diagnosis) -> Result<()> {
    let inline = figures(dg)
        .into_iter()
        .map(|f| {
            Ok(InlineFigure {
                caption: f.caption.into(),
                svg: svg_string(&f.figure).with_context(|| format!("cannot draw {}", f.stem))?,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let page = report_page(&format!("mrtwin diagnose: {name}"), md, &inline);
    write_whole(path, page.as_bytes())
}

/// Residual over time (1 s RMS windows) and the mean signed residual after current steps.
// Several per-sample arrays are read with one index: range loops are clearer.
#[allow(clippy::needless_range_loop)]
fn time_figure(dg: &Diagnosis) -> Figure {
    let d = &dg.data;
    let n = d.len();
    let windows = |pred: &[f64]| {
        let mut pts = Vec::new();
        let mut start = 0;
        while start < n {
            let mut end = start;
            while end < n && d.t[end] - d.t[start] < 1.0 {
                end += 1;
            }
            let ms = (start..end)
                .map(|j| (d.f[j] - pred[j]).powi(2))
                .sum::<f64>()
                / (end - start) as f64;
            pts.push((0.5 * (d.t[start] + d.t[end - 1]), ms.sqrt()));
            start = end;
        }
        pts
    };
    // Mean of residual · sgn(v) · sgn(ΔI) against time since the last current step.
    let imax = d.i.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let tol = (0.02 * imax).max(1e-3);
    let after_step = |pred: &[f64]| {
        let bins = 50usize;
        let mut acc = vec![(0.0, 0usize); bins];
        let mut last: Option<(f64, f64)> = None;
        for j in 1..n {
            if (d.i[j] - d.i[j - 1]).abs() > tol {
                last = Some((d.t[j], (d.i[j] - d.i[j - 1]).signum()));
            }
            if let Some((ts, sg)) = last {
                let b = ((d.t[j] - ts) / 0.002) as usize;
                if b < bins {
                    acc[b].0 += (d.f[j] - pred[j]) * d.v[j].signum() * sg;
                    acc[b].1 += 1;
                }
            }
        }
        acc.iter()
            .enumerate()
            .filter(|(_, a)| a.1 > 0)
            .map(|(b, a)| (2.0 * b as f64, a.0 / a.1 as f64))
            .collect::<Vec<_>>()
    };
    let mk = |label: &str, c, pts| Series {
        label: label.into(),
        colour: c,
        points: pts,
        dashed: false,
    };
    Figure {
        x_label: "time (s) | time since current step (ms)".into(),
        y_label: "residual (N)".into(),
        panels: vec![
            Panel {
                title: "RMS residual over time (1 s windows)".into(),
                series: vec![
                    mk("baseline", PALETTE[1], windows(&dg.baseline_force)),
                    mk("final model", PALETTE[2], windows(&dg.final_force)),
                ],
                legend: None,
            },
            Panel {
                title: "mean residual · sgn v · sgn ΔI after current steps".into(),
                series: vec![
                    mk("baseline", PALETTE[1], after_step(&dg.baseline_force)),
                    mk("final model", PALETTE[2], after_step(&dg.final_force)),
                ],
                legend: None,
            },
        ],
    }
}
