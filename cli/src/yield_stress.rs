//! `mrtwin yield-stress`: the yield point τ0 of the simplified Bodner–Partom law,
//! eq. (5.3) of Skalski & Zalewski (2014), with n and R0 from their fit (5.5).

use anyhow::{bail, Result};
use clap::Args;
use serde::Serialize;
use twin::fluid::{BodnerPartom, BODNER_PARTOM_D0};

use crate::numbers::{finite, positive, trim};

/// Arguments of `mrtwin yield-stress`.
#[derive(Debug, Args)]
pub struct YieldStressArgs {
    /// Coil current i [A] (its magnitude enters (5.5)).
    #[arg(long, value_name = "A", allow_hyphen_values = true)]
    pub current: f64,
    /// Fluid temperature t [°C].
    #[arg(
        long,
        value_name = "C",
        default_value_t = 25.0,
        allow_hyphen_values = true
    )]
    pub temperature: f64,
    /// Gap height h [m] (the paper's gaps: 0.5e-3, 0.7e-3, 1.0e-3).
    #[arg(
        long,
        value_name = "M",
        default_value_t = 0.7e-3,
        allow_hyphen_values = true
    )]
    pub gap: f64,
    /// Plastic shear rate [1/s], in (0, 2·D0) = (0, 2e6).
    #[arg(long, value_name = "1/s", allow_hyphen_values = true)]
    pub shear_rate: f64,
    /// Print one JSON object instead of a sentence.
    #[arg(long)]
    pub json: bool,
}

/// The result: τ0 and the law's parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct YieldStress {
    /// τ0 from (5.3) \[Pa\].
    #[serde(rename = "tau0_Pa")]
    pub tau0_pa: f64,
    /// Rate-sensitivity exponent n from (5.5).
    pub n: f64,
    /// R0 from (5.5), in Pa.
    #[serde(rename = "R0")]
    pub r0_pa: f64,
    /// Unit of `R0`, always "Pa".
    #[serde(rename = "R0_unit")]
    pub r0_unit: &'static str,
    /// D0 \[1/s\].
    #[serde(rename = "D0")]
    pub d0: f64,
}

/// τ0 at current `current_a`, temperature `temperature_c`, gap `gap_m` and plastic shear
/// rate `shear_rate`, with the inputs checked.
pub fn compute(
    current_a: f64,
    temperature_c: f64,
    gap_m: f64,
    shear_rate: f64,
) -> Result<YieldStress> {
    let current_a = finite("--current", current_a)?.abs();
    let temperature_c = finite("--temperature", temperature_c)?;
    let gap_m = positive("--gap", gap_m)?;
    let max_rate = 2.0 * BODNER_PARTOM_D0;
    if !(shear_rate > 0.0 && shear_rate < max_rate) {
        bail!(
            "--shear-rate must lie in (0, {max_rate:e}) 1/s, below 2·D0 of the law (got {shear_rate})"
        );
    }
    let law = BodnerPartom::from_paper(current_a, temperature_c, gap_m);
    if !(law.n > 0.0 && law.r0_pa > 0.0) {
        bail!(
            "eq. (5.5) gives n = {:.4}, R0 = {:.1} kPa at i = {} A, t = {} °C: \
             outside the law's range (n and R0 must be > 0)",
            law.n,
            law.r0_pa * 1e-3,
            trim(current_a, 4),
            trim(temperature_c, 2)
        );
    }
    let tau0_pa = law.yield_point(shear_rate);
    if !tau0_pa.is_finite() {
        bail!("eq. (5.3) has no finite yield point for these inputs");
    }
    Ok(YieldStress {
        tau0_pa,
        n: law.n,
        r0_pa: law.r0_pa,
        r0_unit: "Pa",
        d0: law.d0,
    })
}

/// Run the subcommand.
pub fn run(args: &YieldStressArgs) -> Result<()> {
    let y = compute(args.current, args.temperature, args.gap, args.shear_rate)?;
    if args.json {
        println!("{}", serde_json::to_string(&y)?);
    } else {
        println!(
            "tau0 = {:.1} kPa (n = {:.4}, R0 = {:.1} kPa; D0 = {:e} 1/s; \
             i = {} A, t = {} °C, h = {} mm, rate = {} 1/s)",
            y.tau0_pa * 1e-3,
            y.n,
            y.r0_pa * 1e-3,
            y.d0,
            trim(args.current.abs(), 4),
            trim(args.temperature, 2),
            trim(args.gap * 1e3, 4),
            trim(args.shear_rate, 3),
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_point() {
        let y = compute(1.0, 25.0, 0.7e-3, 73.0).unwrap();
        assert!((y.tau0_pa / 364.6e3 - 1.0).abs() < 5e-3, "{}", y.tau0_pa);
        assert!((y.n - 0.2775).abs() < 1e-12);
        assert!((y.r0_pa / 9257.142857e3 - 1.0).abs() < 1e-9);
    }

    #[test]
    fn rejects_out_of_range() {
        assert!(compute(1.0, 25.0, 0.0, 73.0).is_err());
        assert!(compute(1.0, 25.0, 0.7e-3, 0.0).is_err());
        assert!(compute(1.0, 25.0, 0.7e-3, 2e6).is_err());
        assert!(compute(1.0, 1000.0, 0.7e-3, 73.0).is_err());
    }
}
