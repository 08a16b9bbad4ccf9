//! `mrtwin simulate`: drive one damper model through a test-stand programme and write
//! the recording as CSV (PHYSICS.md format), or as a rosbag2 MCAP bag when `--out` is a
//! directory or a `.mcap` file (see `docs/bags.md`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use bridge::csv::{write_csv, Recording, Sample};
use clap::{Args, ValueEnum};
use twin::models::{build, FluidLaw, ModelKind, ModelParams};
use twin::stand::{run as run_stand, Noise, Programme, SimulatedSample};
use twin::{Effect, EffectSet, EffectsChoice};

use crate::numbers::{finite, non_negative, positive};

/// Node name whose section `--params` reads from a ROS 2 parameter file.
pub const PARAMS_NODE: &str = "mrtwin_stand";

/// Largest recording `simulate` agrees to produce, in samples.
const MAX_SAMPLES: f64 = 5.0e7;

/// Arguments of `mrtwin simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Damper model: bingham, spencer, direct-shear or two-chamber.
    #[arg(long, value_name = "NAME")]
    pub model: String,
    /// Stroke amplitude A [m] of x = A sin(2π f t).
    #[arg(
        long,
        value_name = "M",
        default_value_t = 0.010,
        allow_hyphen_values = true
    )]
    pub amplitude: f64,
    /// Stroke frequencies [Hz], comma separated; one segment each (inner loop).
    #[arg(
        long = "frequency",
        value_name = "HZ[,HZ…]",
        value_delimiter = ',',
        default_value = "1.66,3.33,5",
        allow_hyphen_values = true
    )]
    pub frequencies: Vec<f64>,
    /// Coil currents [A], comma separated; one block of segments each (outer loop).
    #[arg(
        long = "current",
        value_name = "A[,A…]",
        value_delimiter = ',',
        default_value = "0.5,1,2",
        allow_hyphen_values = true
    )]
    pub currents: Vec<f64>,
    /// Duration of each segment [s].
    #[arg(
        long,
        value_name = "S",
        default_value_t = 5.0,
        allow_hyphen_values = true
    )]
    pub duration: f64,
    /// Sample rate [Hz].
    #[arg(
        long,
        value_name = "HZ",
        default_value_t = 400.0,
        allow_hyphen_values = true
    )]
    pub rate: f64,
    /// Force-sensor noise: standard deviation as a fraction of the peak force (0: none).
    #[arg(
        long,
        value_name = "FRACTION",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    pub noise: f64,
    /// Seed of the noise generator (same seed, same recording).
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub seed: u64,
    /// Effects, comma separated ids (fluid_compressibility, gas_spring, seal_friction,
    /// thermal_softening, field_lag, fluid_inertia), `paper`, `all` or `none`; two-chamber
    /// only.
    /// Default: the model's own (two-chamber: fluid_compressibility,gas_spring).
    #[arg(long, value_name = "LIST")]
    pub effects: Option<String>,
    /// Model parameters: YAML file (ROS 2 ros__parameters, node `mrtwin_stand`, or plain)
    /// with sections bingham, spencer, direct_shear, two_chamber (a stand's other keys are
    /// accepted and not used: the flags set the programme).
    #[arg(long, value_name = "FILE.yaml")]
    pub params: Option<PathBuf>,
    /// Two-chamber: constitutive law of the fluid in the gap.
    #[arg(long, value_name = "LAW")]
    pub fluid: Option<FluidArg>,
    /// Two-chamber: effective bulk modulus K [Pa] (fluid_compressibility).
    #[arg(long, value_name = "PA", allow_hyphen_values = true)]
    pub bulk_modulus: Option<f64>,
    /// Two-chamber: gas preload p0 [Pa gauge] (gas_spring).
    #[arg(long, value_name = "PA", allow_hyphen_values = true)]
    pub gas_preload: Option<f64>,
    /// Two-chamber: Coulomb seal friction [N] (seal_friction).
    #[arg(long, value_name = "N", allow_hyphen_values = true)]
    pub seal_friction: Option<f64>,
    /// Two-chamber: field time constant [s] (field_lag).
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    pub field_time_constant: Option<f64>,
    /// Ambient temperature [°C] (default 25).
    #[arg(long, value_name = "C", allow_hyphen_values = true)]
    pub temperature: Option<f64>,
    /// Output: FILE.csv (CSV recording), FILE.mcap (bare MCAP), anything else a rosbag2
    /// bag directory with MCAP storage (`/<name>/sensor/sample`). Parent directories are
    /// created if needed; a bag directory must not exist or be empty.
    #[arg(long, value_name = "FILE.csv|DIR")]
    pub out: PathBuf,
    /// Damper name in a bag: namespace of its topics and the samples' frame_id.
    #[arg(long, value_name = "NAME", default_value = "damper")]
    pub name: String,
}

/// The fluid laws of the two-chamber model, as named on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FluidArg {
    /// Bingham plastic.
    Bingham,
    /// Herschel–Bulkley.
    HerschelBulkley,
    /// Bodner–Partom law of Skalski & Zalewski.
    BodnerPartom,
}

impl From<FluidArg> for FluidLaw {
    fn from(f: FluidArg) -> Self {
        match f {
            FluidArg::Bingham => FluidLaw::Bingham,
            FluidArg::HerschelBulkley => FluidLaw::HerschelBulkley,
            FluidArg::BodnerPartom => FluidLaw::BodnerPartom,
        }
    }
}

/// Run the subcommand.
pub fn run(args: &SimulateArgs) -> Result<()> {
    let kind: ModelKind = args.model.parse()?;
    let effects = match &args.effects {
        Some(choice) => choice.parse::<EffectsChoice>().context("--effects")?,
        None => EffectsChoice::ModelDefault,
    };
    let effects = kind.effects(effects);
    let params = model_params(args, kind, effects)?;
    let programme = programme(args)?;
    let noise = (non_negative("--noise", args.noise)? > 0.0).then_some(Noise {
        fraction: args.noise,
        seed: args.seed,
    });
    let mut model = build(kind, &params, effects)?;

    let start = Instant::now();
    let samples = run_stand(model.as_mut(), &programme, noise);
    let elapsed = start.elapsed();
    check_finite(&samples)?;
    warn_solver_failures(&samples);

    let recording = to_recording(&samples, &args.out);
    let what = crate::convert::write_output(&args.out, &recording, &args.name)?;

    let peak = samples
        .iter()
        .map(|s| s.measured_force_n.abs())
        .fold(0.0, f64::max);
    eprintln!(
        "simulate: model {kind}, effects {effects}: {} samples in {} segments, \
         peak |F| = {peak:.1} N, simulated in {:.2} s; wrote {what} {}",
        samples.len(),
        programme.segments.len(),
        elapsed.as_secs_f64(),
        args.out.display()
    );
    Ok(())
}

/// Defaults, overridden by the parameter file, overridden by the flags.
fn model_params(args: &SimulateArgs, kind: ModelKind, effects: EffectSet) -> Result<ModelParams> {
    let mut params = match &args.params {
        Some(path) => {
            // A stand section (as `mrtwin fit` writes, or a stand's own file): its model
            // sections; its other keys are the live stand's.
            launch_config::load_params::<node::stand::StandParams>(path, PARAMS_NODE)
                .context("--params")?
                .model_params()
        }
        None => ModelParams::default(),
    };
    // Each effect-parameter flag with the effect it tunes.
    let overrides = [
        (
            "--bulk-modulus",
            args.bulk_modulus,
            Effect::FluidCompressibility,
        ),
        ("--gas-preload", args.gas_preload, Effect::GasSpring),
        ("--seal-friction", args.seal_friction, Effect::SealFriction),
        (
            "--field-time-constant",
            args.field_time_constant,
            Effect::FieldLag,
        ),
    ];
    let mut given = overrides
        .iter()
        .filter(|(_, value, _)| value.is_some())
        .map(|(flag, _, _)| *flag)
        .chain(args.fluid.map(|_| "--fluid"));
    if kind != ModelKind::TwoChamber {
        if let Some(flag) = given.next() {
            bail!("{flag} applies to the two-chamber model only (model is {kind})");
        }
        return Ok(params);
    }
    for (flag, value, effect) in overrides {
        if value.is_some() && !effects.has(effect) {
            eprintln!(
                "warning: {flag} has no effect unless `{effect}` is among the effects ({effects})"
            );
        }
    }
    let tc = &mut params.two_chamber;
    if let Some(k) = args.bulk_modulus {
        tc.bulk_modulus_pa = positive("--bulk-modulus", k)?;
    }
    if let Some(p) = args.gas_preload {
        tc.gas_preload_pa = positive("--gas-preload", p)?;
    }
    if let Some(f) = args.seal_friction {
        tc.seal_friction_n = non_negative("--seal-friction", f)?;
    }
    if let Some(t) = args.field_time_constant {
        tc.field_time_constant_s = positive("--field-time-constant", t)?;
    }
    if let Some(law) = args.fluid {
        tc.fluid.law = law.into();
    }
    Ok(params)
}

/// The programme of the flags: currents (outer) × frequencies (inner).
fn programme(args: &SimulateArgs) -> Result<Programme> {
    let amplitude = positive("--amplitude", args.amplitude)?;
    let duration = positive("--duration", args.duration)?;
    let rate = positive("--rate", args.rate)?;
    if args.frequencies.is_empty() || args.currents.is_empty() {
        bail!("--frequency and --current need at least one value each");
    }
    for &f in &args.frequencies {
        positive("--frequency", f)?;
        if rate <= 2.0 * f {
            bail!("--rate {rate} Hz is too low for {f} Hz: it must exceed twice the frequency");
        }
    }
    for &i in &args.currents {
        finite("--current", i)?;
    }
    if duration * rate < 1.0 {
        bail!("--duration {duration} s at --rate {rate} Hz gives no sample per segment");
    }
    let segments = (args.frequencies.len() * args.currents.len()) as f64;
    if segments * duration * rate > MAX_SAMPLES {
        bail!(
            "the programme would have {:.0} samples (limit {MAX_SAMPLES:.0}); \
             lower --duration or --rate",
            segments * duration * rate
        );
    }
    let mut programme =
        Programme::grid(amplitude, &args.frequencies, &args.currents, duration, rate);
    if let Some(t) = args.temperature {
        programme.ambient_temperature_c = finite("--temperature", t)?;
    }
    Ok(programme)
}

/// An error if the model produced a non-finite force anywhere.
pub fn check_finite(samples: &[SimulatedSample]) -> Result<()> {
    match samples.iter().find(|s| !s.measured_force_n.is_finite()) {
        Some(s) => bail!(
            "the model produced a non-finite force at t = {} s (segment {}); check the parameters",
            s.time_s,
            s.segment + 1
        ),
        None => Ok(()),
    }
}

/// Say on stderr on how many samples the model's implicit solver did not converge (its
/// state held for that step; [`twin::DamperOutput::solver_failed`]), and where first.
fn warn_solver_failures(samples: &[SimulatedSample]) {
    let mut failed = samples.iter().filter(|s| s.output.solver_failed);
    if let Some(first) = failed.next() {
        eprintln!(
            "simulate: warning: the model's implicit solver did not converge on {} samples \
             (first at t = {} s, segment {}); its state was held there: check the parameters",
            1 + failed.count(),
            first.time_s,
            first.segment + 1
        );
    }
}

/// The simulated samples as a recording: the measured (noisy) force, and the model's
/// fluid temperature.
pub fn to_recording(samples: &[SimulatedSample], source: &Path) -> Recording {
    Recording {
        samples: samples
            .iter()
            .map(|s| Sample {
                time_s: s.time_s,
                displacement_m: s.input.displacement_m,
                velocity_m_s: s.input.velocity_m_s,
                force_n: s.measured_force_n,
                current_a: s.input.current_a,
                temperature_c: Some(s.output.fluid_temperature_c),
            })
            .collect(),
        velocity_derived: false,
        has_temperature: true,
        source: source.display().to_string(),
    }
}

/// Write `recording` to `path`, creating its directory first.
pub fn write_recording(path: &Path, recording: &Recording) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create directory {}", dir.display()))?;
    }
    write_csv(path, recording)?;
    Ok(())
}
