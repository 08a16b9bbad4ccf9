//! `mrtwin replay INPUT`: feed a recording (bag or CSV) through the twin — the same
//! pipeline as the live node, driven by the recorded timestamps — and write the twin's
//! outputs to CSV or a new bag, or publish them (with `/clock`) on the transports.
//!
//! Deterministic: the pipeline uses no wall clock and no randomness, the CSV writes every
//! number in Rust's shortest round-trip form, and bag log times are the sample stamps, so
//! two replays of the same input give byte-identical output.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use bridge::bag::{BagWriter, BagWriterOptions};
use bridge::transport::{Message, Topic, Transport};
use clap::Args;
use launch_config::load_params;
use msgs::{Clock, Time};
use node::conditioning::SensorSample;
use node::config::{TwinNodeParams, TWIN_NODE};
use node::core::TwinCore;
use node::diagnostics::level_byte;
use node::pipeline::{Processed, TwinPipeline};
use node::transports::open;

/// Arguments of `mrtwin replay`.
#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// Recording: a rosbag2 directory, an .mcap file or a CSV file.
    pub input: PathBuf,
    /// Pace: `max` (as fast as possible), `realtime`, or a factor of real time (e.g. 2).
    #[arg(long, value_name = "max|realtime|FACTOR", default_value = "max")]
    pub rate: String,
    /// Publish the outputs and /clock on the transports of the parameter file.
    #[arg(long)]
    pub publish: bool,
    /// Output: FILE.csv (one row per input sample) or a bag directory.
    #[arg(long, value_name = "FILE.csv|DIR")]
    pub out: Option<PathBuf>,
    /// Twin parameter file (ROS 2 convention, section `mrtwin_twin`).
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// Model (overrides the parameter file).
    #[arg(long, value_name = "NAME")]
    pub model: Option<String>,
    /// Effects of the two-chamber model (overrides the parameter file).
    #[arg(long, value_name = "IDS")]
    pub effects: Option<String>,
    /// Node name the replay speaks as (names the `/diagnostics` statuses): the twin's by
    /// default, so a replay of a live run publishes the live run's bytes.
    #[arg(long, value_name = "/NS/NAME", default_value = "/mrtwin_twin")]
    pub node_name: String,
}

/// Columns of the CSV output.
pub const CSV_HEADER: &str = "time_s,current_A,force_N,force_predicted_N,residual_N,tau0_Pa,tau0_std_Pa,health_level,displacement_m,velocity_m_s,dissipated_power_W,fluid_temperature_C,dropped";

fn pace(rate: &str) -> Result<Option<f64>> {
    match rate {
        "max" => Ok(None),
        "realtime" => Ok(Some(1.0)),
        f => match f.parse::<f64>() {
            Ok(x) if x.is_finite() && x > 0.0 => Ok(Some(x)),
            _ => bail!("--rate must be max, realtime or a positive factor, got '{f}'"),
        },
    }
}

/// Twin parameters of a replay.
pub fn replay_params(args: &ReplayArgs) -> Result<TwinNodeParams> {
    let mut p: TwinNodeParams = match &args.params {
        Some(f) => load_params(f, TWIN_NODE)?,
        None => TwinNodeParams::default(),
    };
    if let Some(m) = &args.model {
        p.model = m.parse().context("--model")?;
    }
    if let Some(e) = &args.effects {
        p.effects = e.parse().context("--effects")?;
    }
    p.validate()?;
    Ok(p)
}

enum Sink {
    None,
    Csv(PathBuf, String),
    Bag(Box<BagWriter>),
}

fn ns(t: f64) -> u64 {
    Time::from_secs_f64(t).as_nanos().max(0) as u64
}

/// `mrtwin replay`.
pub fn run(args: &ReplayArgs) -> Result<()> {
    let pace = pace(&args.rate)?;
    let params = replay_params(args)?;
    let rec = bridge::open_recording(&args.input)
        .with_context(|| format!("read {}", args.input.display()))?;
    if rec.is_empty() {
        bail!("{}: no samples to replay", args.input.display());
    }
    let mut core = TwinCore::new(&params, &args.node_name)?;
    let mut sink = Sink::open(args.out.as_deref(), rec.len())?;
    let mut publisher = match args.publish {
        true => Some(Publisher::open(&params, &args.node_name)?),
        false => None,
    };
    let damper = params.damper.clone();
    let start = Instant::now();
    let t0 = rec.samples[0].time_s;
    let mut stepped = 0u64;
    for s in &rec.samples {
        if let Some(factor) = pace {
            let due = start + Duration::from_secs_f64(((s.time_s - t0) / factor).max(0.0));
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
        }
        let sample = SensorSample::from_recording(s);
        // Replay's clock is the recording's: the core never sees the samples stop.
        let out = core.on_sample(&sample, s.time_s);
        let processed = out.processed;
        stepped += u64::from(matches!(processed, Processed::Stepped(_)));
        let messages: Vec<Message> = out.into_messages().collect();
        sink.write(&damper, &sample, &processed, core.pipeline(), &messages)?;
        if let Some(p) = publisher.as_mut() {
            p.publish(&messages, s.time_s)?;
        }
    }
    let elapsed = start.elapsed().as_secs_f64();
    sink.finish()?;
    let pipeline = core.pipeline();
    let c = pipeline.counters();
    tracing::info!(
        "replayed {} samples ({} stepped, {} with a channel stuck at one value and not judged; {} dropped: NaN {}, duplicate {}, out of order {}; {} gaps) with {} in {:.3} s ({:.0} samples/s)",
        rec.len(),
        stepped,
        c.stuck,
        c.non_finite + c.duplicates + c.out_of_order,
        c.non_finite,
        c.duplicates,
        c.out_of_order,
        c.gaps,
        pipeline.model_id(),
        elapsed,
        rec.len() as f64 / elapsed.max(1e-9)
    );
    Ok(())
}

impl Sink {
    /// The sink of `--out`: none, a CSV (by extension) or a bag directory.
    fn open(out: Option<&Path>, rows: usize) -> Result<Self> {
        Ok(match out {
            None => Sink::None,
            Some(p) if p.extension().is_some_and(|e| e.eq_ignore_ascii_case("csv")) => {
                let mut s = String::with_capacity(rows * 160);
                s.push_str(CSV_HEADER);
                s.push('\n');
                Sink::Csv(p.to_path_buf(), s)
            }
            Some(p) => Sink::Bag(Box::new(
                BagWriter::create(p, BagWriterOptions::default())
                    .with_context(|| format!("create bag {}", p.display()))?,
            )),
        })
    }

    /// One sample: a CSV row, or the sample and its messages in the bag at its stamp.
    fn write(
        &mut self,
        damper: &str,
        sample: &SensorSample,
        processed: &Processed,
        pipeline: &TwinPipeline,
        messages: &[Message],
    ) -> Result<()> {
        match self {
            Sink::None => {}
            Sink::Csv(_, buf) => csv_row(buf, sample, processed, pipeline),
            Sink::Bag(w) => {
                let t = ns(sample.time_s);
                w.write_message(damper, &Message::Sample(sample.to_msg(damper)), t)?;
                for m in messages {
                    w.write_message(damper, m, t)?;
                }
            }
        }
        Ok(())
    }

    fn finish(self) -> Result<()> {
        match self {
            Sink::None => {}
            Sink::Csv(path, buf) => crate::output::write_whole(&path, buf.as_bytes())?,
            Sink::Bag(w) => {
                w.finish()?;
            }
        }
        Ok(())
    }
}

/// `--publish`: the core's messages and `/clock` on the transports of the parameters.
struct Publisher {
    transports: Vec<Box<dyn Transport>>,
}

impl Publisher {
    fn open(params: &TwinNodeParams, node_name: &str) -> Result<Self> {
        let settings = params.transport_settings(node_name);
        let topics = [
            Topic::Output,
            Topic::PredictedForce,
            Topic::YieldEstimate,
            Topic::Diagnostics,
            Topic::Clock,
        ];
        let transports = params
            .transports
            .iter()
            .map(|&k| open(k, &settings, &topics, &[]))
            .collect::<Result<_, _>>()?;
        Ok(Self { transports })
    }

    fn publish(&mut self, messages: &[Message], time_s: f64) -> Result<()> {
        let clock = Message::Clock(Clock {
            clock: Time::from_secs_f64(time_s),
        });
        for t in &mut self.transports {
            for m in messages.iter().chain([&clock]) {
                t.publish(m)?;
            }
        }
        Ok(())
    }
}

fn csv_row(buf: &mut String, s: &SensorSample, p: &Processed, pipeline: &TwinPipeline) {
    let nan = f64::NAN;
    // A stepped row shows the conditioned sample: the coil current (a command voltage
    // converted), and no residual where a channel is stuck (it is not judged).
    let (current, pred, res, power, temp, est, level, dropped) = match p {
        Processed::Stepped(st) => (
            st.sample.current_a,
            st.output.force_n,
            if st.stuck.is_some() {
                nan
            } else {
                st.residual_n
            },
            st.output.dissipated_power_w,
            st.output.fluid_temperature_c,
            st.estimate,
            st.health,
            0,
        ),
        Processed::Dropped(_) => (
            s.current_a,
            nan,
            nan,
            nan,
            nan,
            None,
            pipeline.health_level(),
            1,
        ),
    };
    let _ = writeln!(
        buf,
        "{},{},{},{},{},{},{},{},{},{},{},{},{}",
        s.time_s,
        current,
        s.force_n,
        pred,
        res,
        est.map_or(nan, |e| e.tau0_pa),
        est.map_or(nan, |e| e.tau0_std_pa),
        level_byte(level),
        s.displacement_m,
        s.velocity_m_s,
        power,
        temp,
        dropped
    );
}
