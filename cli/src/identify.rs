//! `mrtwin identify`: the offline identification pipeline of Skalski & Zalewski (2014) on
//! CSV recordings (`estimation::identify`): per recording the shear rate and the yield point
//! of the first loading, per current n and R0 of the Bodner–Partom law by
//! Levenberg–Marquardt on (5.3) with D0 = 10⁶ 1/s, then their dependence on current (and
//! temperature where recorded) in the form of (5.5).
//!
//! Each recording is one test at one current, starting from rest (as in the paper); three or
//! more recordings at distinct shear rates are needed per current.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use bridge::csv::read_csv;
use clap::Args;
use estimation::identify::{identify, Identification, TestRecord};
use serde_json::json;
use twin::models::DirectShearParams;

use crate::numbers::positive;

/// Arguments of `mrtwin identify`.
#[derive(Debug, Args)]
pub struct IdentifyArgs {
    /// CSV recordings (PHYSICS.md format), one test from rest at one current each.
    #[arg(required = true, value_name = "RECORDING")]
    pub recordings: Vec<PathBuf>,
    /// Gap height h [m]: γ = Δx/h (4.1). Default: the direct-shear model's 0.7 mm.
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub gap: Option<f64>,
    /// Shear area A [m²]: τ = F/A (4.1), A = 2π r l (4.3). Default: the direct-shear model's.
    #[arg(long, value_name = "M2", allow_hyphen_values = true)]
    pub area: Option<f64>,
    /// Also write the results as JSON to this file.
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
}

/// Largest spread of the current within one recording \[A\].
const CURRENT_TOLERANCE_A: f64 = 0.01;

fn load(path: &Path) -> Result<TestRecord> {
    let rec = read_csv(path).with_context(|| format!("cannot read {}", path.display()))?;
    let (lo, hi) = rec
        .samples
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
            (lo.min(s.current_a), hi.max(s.current_a))
        });
    if rec.samples.is_empty() {
        bail!("{}: no samples", path.display());
    }
    if hi - lo > CURRENT_TOLERANCE_A {
        bail!(
            "{}: the current varies from {lo} A to {hi} A; identify needs one test at one current per recording",
            path.display()
        );
    }
    let temps: Vec<f64> = rec.samples.iter().filter_map(|s| s.temperature_c).collect();
    Ok(TestRecord {
        source: path.display().to_string(),
        current_a: 0.5 * (lo + hi),
        temperature_c: (!temps.is_empty()).then(|| temps.iter().sum::<f64>() / temps.len() as f64),
        time_s: rec.samples.iter().map(|s| s.time_s).collect(),
        displacement_m: rec.samples.iter().map(|s| s.displacement_m).collect(),
        force_n: rec.samples.iter().map(|s| s.force_n).collect(),
    })
}

/// Run `mrtwin identify`.
pub fn run(args: &IdentifyArgs) -> Result<()> {
    let defaults = DirectShearParams::default();
    let gap = positive("--gap", args.gap.unwrap_or(defaults.gap_height_m))?;
    let area = positive("--area", args.area.unwrap_or(defaults.shear_area_m2()))?;
    let tests = args
        .recordings
        .iter()
        .map(|p| load(p))
        .collect::<Result<Vec<_>>>()?;
    let id = identify(&tests, gap, area).map_err(|e| anyhow::anyhow!("{e}"))?;
    print!("{}", text(&id));
    if let Some(out) = &args.json {
        let s = serde_json::to_string_pretty(&to_json(&id))?;
        std::fs::write(out, s + "\n").with_context(|| format!("cannot write {}", out.display()))?;
    }
    Ok(())
}

fn text(id: &Identification) -> String {
    let mut s = format!(
        "gap h = {} m, shear area A = {:.4e} m², D0 = 1e6 1/s\n\nfirst loadings:\n",
        id.gap_m, id.area_m2
    );
    for t in &id.tests {
        s += &format!(
            "  {}: I {} A, shear rate {:.1} 1/s, tau0 {:.1} kPa, G {:.3} MPa\n",
            t.source,
            t.current_a,
            t.shear_rate_per_s,
            t.tau0_pa / 1e3,
            t.shear_modulus_pa / 1e6
        );
    }
    s += "\nBodner–Partom law (5.3) per current:\n";
    for l in &id.laws {
        s += &format!(
            "  I {} A (t {:.1} °C): n = {:.4} ± {:.4}, R0 = {:.1} ± {:.1} kPa, residual RMS {:.3} kPa\n",
            l.current_a,
            l.temperature_c,
            l.n,
            l.n_se,
            l.r0_pa / 1e3,
            l.r0_se_pa / 1e3,
            l.rms_pa / 1e3
        );
        for (g, t, r) in &l.residuals {
            s += &format!(
                "    shear rate {g:.1} 1/s: tau0 {:.2} kPa, fit − data {:+.3} kPa\n",
                t / 1e3,
                r / 1e3
            );
        }
    }
    if let Some(d) = &id.dependence {
        let term = |c: &[estimation::identify::Coefficient], k: usize| {
            format!("({:.5} ± {:.5})", c[k].value, c[k].se)
        };
        s += "\ndependence on current (5.5):\n";
        if d.with_temperature {
            s += &format!(
                "  n      = {} + {} i + {} t\n  R0 h   = {} + {} i + {} t  [kPa·m]\n",
                term(&d.n, 0),
                term(&d.n, 1),
                term(&d.n, 2),
                term(&d.r0_h_kpa_m, 0),
                term(&d.r0_h_kpa_m, 1),
                term(&d.r0_h_kpa_m, 2)
            );
        } else {
            s += &format!(
                "  n      = {} + {} i   (at {:.1} °C)\n  R0 h   = {} + {} i   [kPa·m] (at {:.1} °C)\n",
                term(&d.n, 0),
                term(&d.n, 1),
                d.temperature_c,
                term(&d.r0_h_kpa_m, 0),
                term(&d.r0_h_kpa_m, 1),
                d.temperature_c
            );
        }
    }
    s
}

fn to_json(id: &Identification) -> serde_json::Value {
    let coef = |c: &[estimation::identify::Coefficient]| {
        c.iter()
            .map(|c| json!({"value": c.value, "se": c.se}))
            .collect::<Vec<_>>()
    };
    json!({
        "gap_m": id.gap_m,
        "area_m2": id.area_m2,
        "D0": twin::fluid::BODNER_PARTOM_D0,
        "tests": id.tests.iter().map(|t| json!({
            "source": t.source,
            "current_A": t.current_a,
            "temperature_C": t.temperature_c,
            "shear_rate_per_s": t.shear_rate_per_s,
            "tau0_Pa": t.tau0_pa,
            "G_Pa": t.shear_modulus_pa,
        })).collect::<Vec<_>>(),
        "laws": id.laws.iter().map(|l| json!({
            "current_A": l.current_a,
            "temperature_C": l.temperature_c,
            "n": l.n,
            "n_se": l.n_se,
            "R0_Pa": l.r0_pa,
            "R0_se_Pa": l.r0_se_pa,
            "rms_Pa": l.rms_pa,
            "residuals": l.residuals.iter().map(|(g, t, r)| json!({
                "shear_rate_per_s": g, "tau0_Pa": t, "fit_minus_data_Pa": r
            })).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
        "dependence": id.dependence.as_ref().map(|d| json!({
            "n": coef(&d.n),
            "R0_h_kPa_m": coef(&d.r0_h_kpa_m),
            "terms": if d.with_temperature { vec!["1", "i", "t"] } else { vec!["1", "i"] },
            "temperature_C": d.temperature_c,
        })),
    })
}
