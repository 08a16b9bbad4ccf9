//! The test stand as a live sensor stream: a damper model driven through a programme of
//! harmonic strokes (the programme repeats), sampled at `rate_hz` with real-time pacing,
//! with force-sensor noise, published as `DamperSample` on the chosen transports. Faults
//! can be injected to exercise the twin: dropped, duplicated, swapped (out-of-order) and
//! NaN samples, and a period of silence.
//!
//! With the ROS 2 transport the stand serves its settings as ROS 2 parameters
//! ([`StandParameters`], through [`crate::parameters`]); a set takes effect at the next sample
//! ([`StandPlayer::retune`]).

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use bridge::transport::{Message, Topic, Transport};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use twin::models::{
    build, BinghamParams, DirectShearParams, ModelKind, ModelParams, SpencerParams,
    TwoChamberParams,
};
use twin::stand::Programme;
use twin::EffectsChoice;

use crate::conditioning::SensorSample;
use crate::config::InvalidParam;
use crate::parameters::{Served, ServedSettings};
use crate::runner::{NodeError, StopWhen};
use crate::transports::{open_serving, TransportKind, TransportSettings};

/// Faults to inject (probabilities per sample).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct Faults {
    /// Drop the sample.
    pub drop_probability: f64,
    /// Send the sample twice.
    pub duplicate_probability: f64,
    /// Swap the sample with the next one (out-of-order stamps).
    pub swap_probability: f64,
    /// Replace the force with NaN.
    pub nan_probability: f64,
    /// Go silent at this time since start \[s\] …
    pub silence_at_s: Option<f64>,
    /// … for this long \[s\].
    pub silence_for_s: f64,
}

/// Parameters of the stand node (`mrtwin stand`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StandParams {
    /// Damper name.
    pub damper: String,
    /// Model that plays the damper.
    pub model: ModelKind,
    /// Its effects (see the twin node).
    pub effects: EffectsChoice,
    /// Stroke amplitude \[m\].
    pub amplitude_m: f64,
    /// Frequencies \[Hz\] (inner loop of the programme).
    pub frequencies_hz: Vec<f64>,
    /// Currents \[A\] (outer loop).
    pub currents_a: Vec<f64>,
    /// Duration of each segment \[s\].
    pub segment_duration_s: f64,
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// Force-sensor noise, standard deviation \[N\].
    pub noise_n: f64,
    /// Random seed (noise and faults).
    pub seed: u64,
    /// Ambient temperature \[°C\].
    pub ambient_temperature_c: f64,
    /// Publish the temperature channel (else NaN: not measured).
    pub temperature_channel: bool,
    /// Transports to publish on.
    pub transports: Vec<TransportKind>,
    /// Fault injection.
    pub faults: Faults,
    /// `bingham` parameters.
    pub bingham: BinghamParams,
    /// `spencer` parameters.
    pub spencer: SpencerParams,
    /// `direct-shear` parameters.
    pub direct_shear: DirectShearParams,
    /// `two-chamber` parameters.
    pub two_chamber: TwoChamberParams,
    /// zenoh settings.
    pub zenoh: bridge::zenoh::ZenohConfig,
    /// ROS 2 settings.
    pub ros2: bridge::ros2::Ros2Config,
    /// iceoryx2 settings.
    pub iceoryx2: bridge::iceoryx2::Iceoryx2Config,
}

impl Default for StandParams {
    fn default() -> Self {
        Self {
            damper: "damper".into(),
            model: ModelKind::TwoChamber,
            effects: EffectsChoice::ModelDefault,
            amplitude_m: 0.010,
            frequencies_hz: vec![1.0, 2.0, 4.0],
            currents_a: vec![0.5, 1.0, 2.0],
            segment_duration_s: 3.0,
            rate_hz: 1000.0,
            noise_n: 5.0,
            seed: 1,
            ambient_temperature_c: 25.0,
            temperature_channel: false,
            transports: vec![TransportKind::Zenoh],
            faults: Faults::default(),
            bingham: Default::default(),
            spencer: Default::default(),
            direct_shear: Default::default(),
            two_chamber: Default::default(),
            zenoh: Default::default(),
            ros2: Default::default(),
            iceoryx2: Default::default(),
        }
    }
}

impl StandParams {
    /// The programme.
    pub fn programme(&self) -> Programme {
        let mut p = Programme::grid(
            self.amplitude_m,
            &self.frequencies_hz,
            &self.currents_a,
            self.segment_duration_s,
            self.rate_hz,
        );
        p.ambient_temperature_c = self.ambient_temperature_c;
        p
    }

    /// The damper model that plays the stand, with its effects.
    fn model(&self) -> Result<Box<dyn twin::DamperModel>, NodeError> {
        Ok(build(
            self.model,
            &self.model_params(),
            self.model.effects(self.effects),
        )?)
    }

    /// The force sensor's noise (validated: σ ≥ 0).
    fn noise(&self) -> Normal<f64> {
        Normal::new(0.0, self.noise_n.max(1e-300)).expect("σ > 0")
    }

    /// The model parameters of the four sections.
    pub fn model_params(&self) -> ModelParams {
        ModelParams {
            bingham: self.bingham.clone(),
            spencer: self.spencer.clone(),
            direct_shear: self.direct_shear.clone(),
            two_chamber: self.two_chamber.clone(),
        }
    }

    fn validate(&self) -> Result<(), InvalidParam> {
        let bad = |key, reason: String| Err(InvalidParam { key, reason });
        crate::config::check_laws_in_current(&self.two_chamber.fluid)?;
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0 && self.rate_hz <= 1e6) {
            return bad(
                "rate_hz",
                format!("must be in (0, 1e6], got {}", self.rate_hz),
            );
        }
        if self.frequencies_hz.is_empty() || self.currents_a.is_empty() {
            return bad(
                "frequencies_hz",
                "the programme needs at least one frequency and one current".into(),
            );
        }
        if self.segment_duration_s.is_nan() || self.segment_duration_s <= 0.0 {
            return bad("segment_duration_s", "must be positive".into());
        }
        if self.noise_n.is_nan() || self.noise_n < 0.0 {
            return bad("noise_n", "must be ≥ 0".into());
        }
        Ok(())
    }
}

impl ServedSettings for StandParams {
    /// The pacing (`rate_hz`) and the random stream (`seed`) are fixed for a run.
    const RESTART_ONLY: &'static [&'static str] = &[
        "damper",
        "transports",
        "rate_hz",
        "seed",
        "zenoh",
        "ros2",
        "iceoryx2",
    ];

    /// Validated, and its model with its effects built.
    fn check(&self) -> Result<(), String> {
        StandPlayer::new(self)
            .map(|_| ())
            .map_err(|e| e.to_string())
    }
}

/// The stand node's served parameters ([`crate::parameters`]).
pub type StandParameters = Served<StandParams>;

/// What the stand did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StandSummary {
    /// Samples generated.
    pub generated: u64,
    /// Messages published (after faults).
    pub published: u64,
    /// Publish errors.
    pub errors: u64,
    /// Largest lateness behind the real-time schedule \[s\].
    pub max_lateness_s: f64,
}

/// The stand node.
pub struct StandNode {
    params: StandParams,
    transports: Vec<Box<dyn Transport>>,
    /// The parameters served to the middleware's tools (ROS 2 parameters); a set is
    /// taken before the next sample.
    served: Arc<StandParameters>,
}

impl StandNode {
    /// Open the transports (the ROS 2 one serves the stand's parameters).
    pub fn new(params: StandParams, node_name: &str) -> Result<Self, NodeError> {
        params.validate()?;
        let settings = TransportSettings::new(
            &params.damper,
            node_name,
            &params.ros2,
            &params.zenoh,
            &params.iceoryx2,
        );
        let served = StandParameters::new(&params);
        let mut transports = Vec::new();
        for &k in &params.transports {
            let serve: Arc<dyn bridge::params::ParamService> = served.clone();
            transports.push(open_serving(
                k,
                &settings,
                &[Topic::Sample],
                &[],
                Some(serve),
            )?);
        }
        Ok(Self {
            params,
            transports,
            served,
        })
    }

    /// Play until `stop` or `duration` (wall clock).
    pub fn run(
        &mut self,
        stop: Option<&AtomicBool>,
        duration: Option<Duration>,
    ) -> Result<StandSummary, NodeError> {
        let mut player = StandPlayer::new(&self.params)?;
        player.set_epoch(wall_clock_s());
        let mut summary = StandSummary::default();
        let mut batch = Vec::new();
        run_paced(
            self.params.rate_hz,
            stop,
            duration,
            &mut summary,
            |k, summary| -> Result<(), NodeError> {
                if let Some(params) = self.served.take_pending() {
                    player.retune(&params)?;
                    tracing::info!("took a ROS 2 parameter set at sample {k}");
                }
                player.next(&mut batch);
                summary.generated += 1;
                for s in &batch {
                    let msg = Message::Sample(s.to_msg(&self.params.damper));
                    for t in &mut self.transports {
                        publish_sample(t.as_mut(), &self.params.damper, &msg, summary);
                    }
                }
                Ok(())
            },
        )?;
        Ok(summary)
    }
}

/// Call `tick(k, summary)` at `start + k / rate_hz` in real time ([`pace`]) for k = 0, 1, …
/// until `stop` is set or tick `k` would fall at or after `duration`; the lateness behind
/// the schedule goes into `summary`. The pacing of the stand node and of the fleet's stands.
pub fn run_paced<E>(
    rate_hz: f64,
    stop: Option<&AtomicBool>,
    duration: Option<Duration>,
    summary: &mut StandSummary,
    mut tick: impl FnMut(u64, &mut StandSummary) -> Result<(), E>,
) -> Result<(), E> {
    let start = Instant::now();
    let dt = 1.0 / rate_hz;
    let until = StopWhen {
        flag: stop,
        deadline: duration.map(|d| start + d),
    };
    for k in 0u64.. {
        let due = start + Duration::from_secs_f64(k as f64 * dt);
        if until.reached(due) {
            break;
        }
        pace(due, summary);
        tick(k, summary)?;
    }
    Ok(())
}

/// Publish one of `damper`'s sample messages on `transport`, counted in `summary` (a
/// failure is logged and counted as an error); whether it went out.
pub fn publish_sample(
    transport: &mut dyn Transport,
    damper: &str,
    msg: &Message,
    summary: &mut StandSummary,
) -> bool {
    match transport.publish(msg) {
        Ok(()) => {
            summary.published += 1;
            true
        }
        Err(e) => {
            tracing::warn!(damper, transport = transport.name(), error = %e, "publish failed");
            summary.errors += 1;
            false
        }
    }
}

/// The stand's stream without the pacing or the transports: its model driven through the
/// programme, one sample per [`StandPlayer::next`] (sample `k` stamped `epoch + k / rate`,
/// the epoch set by the pacing loop),
/// noise and faults applied. The stand node paces one; the fleet paces many in one loop.
pub struct StandPlayer {
    params: StandParams,
    model: Box<dyn twin::DamperModel>,
    programme: Programme,
    cycle: usize,
    noise: Normal<f64>,
    rng: rand::rngs::StdRng,
    epoch0: f64,
    held: Option<SensorSample>,
    k: u64,
    /// The sample at which the present programme started (0, or the sample after a
    /// retune that changed it).
    programme_start: u64,
    /// The model starts afresh at the next sample (the first, or after a retune).
    restart: bool,
}

impl StandPlayer {
    /// Build the model of `params` (validated first). Stamps start at
    /// [`StandPlayer::set_epoch`]'s epoch.
    pub fn new(params: &StandParams) -> Result<Self, NodeError> {
        params.validate()?;
        let p = params.clone();
        let model = p.model()?;
        let programme = p.programme();
        let cycle = programme.sample_count().max(1);
        let noise = p.noise();
        let rng = rand::rngs::StdRng::seed_from_u64(p.seed);
        Ok(Self {
            params: p,
            model,
            programme,
            cycle,
            noise,
            rng,
            epoch0: 0.0,
            held: None,
            k: 0,
            programme_start: 0,
            restart: true,
        })
    }

    /// Take new parameters (checked as at [`StandPlayer::new`]) from the next sample on;
    /// the clock, the random stream and a held (swapped) sample go on. A change of the
    /// model, its parameters or effects rebuilds the model; a change of the programme
    /// (amplitude, frequencies, currents, segment length, ambient temperature) starts the
    /// new programme from its first segment. Either way the model starts afresh at the
    /// next sample, as at the first. Noise, faults and the temperature channel change
    /// without a restart. The sample rate and the seed are fixed for a run (a change is
    /// refused).
    pub fn retune(&mut self, params: &StandParams) -> Result<(), NodeError> {
        params.validate()?;
        let p = &self.params;
        if (params.rate_hz, params.seed) != (p.rate_hz, p.seed) {
            return Err(InvalidParam {
                key: "rate_hz",
                reason: "the sample rate and the seed are fixed for a run".into(),
            }
            .into());
        }
        if (params.model, params.effects, params.model_params())
            != (p.model, p.effects, p.model_params())
        {
            self.model = params.model()?;
            self.restart = true;
        }
        let programme = params.programme();
        if programme != self.programme {
            self.cycle = programme.sample_count().max(1);
            self.programme = programme;
            self.programme_start = self.k;
            self.restart = true;
        }
        self.noise = params.noise();
        self.params = params.clone();
        Ok(())
    }

    /// Stamp sample `k` at `epoch_s + k / rate` (wall clock, s since the Unix epoch): the
    /// instant the caller's pacing starts from. Without it, the first sample's wall clock.
    pub fn set_epoch(&mut self, epoch_s: f64) {
        self.epoch0 = epoch_s;
    }

    /// The damper's name.
    pub fn damper(&self) -> &str {
        &self.params.damper
    }

    /// Step the model by one sample period and put into `batch` (cleared first) what the
    /// sensor stream carries for it: nothing (dropped, or in a silence), the sample, or
    /// two or three after a swap or a duplicate.
    pub fn next(&mut self, batch: &mut Vec<SensorSample>) {
        batch.clear();
        let p = &self.params;
        let k = self.k;
        self.k += 1;
        let dt = 1.0 / p.rate_hz;
        let at = (k - self.programme_start) as usize % self.cycle;
        let (_, _, input) = self.programme.input_at(at);
        if k == 0 && self.epoch0 == 0.0 {
            self.epoch0 = wall_clock_s();
        }
        let out = if std::mem::take(&mut self.restart) {
            self.model.reset(&input);
            self.model.step(&input, 0.0)
        } else {
            self.model.step(&input, dt)
        };
        let t_rel = k as f64 * dt;
        let f = &p.faults;
        if f.silence_at_s
            .is_some_and(|t0| t_rel >= t0 && t_rel < t0 + f.silence_for_s)
        {
            return;
        }
        let sample = SensorSample {
            time_s: self.epoch0 + t_rel,
            displacement_m: input.displacement_m,
            velocity_m_s: input.velocity_m_s,
            force_n: out.force_n
                + if p.noise_n > 0.0 {
                    self.noise.sample(&mut self.rng)
                } else {
                    0.0
                },
            current_a: input.current_a,
            temperature_c: if p.temperature_channel {
                out.fluid_temperature_c
            } else {
                f64::NAN
            },
        };
        batch.extend(f.apply(sample, &mut self.rng, &mut self.held));
    }
}

/// Seconds since the Unix epoch, now.
pub fn wall_clock_s() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// Sleep, then spin for the last 200 µs, until `due`; a sample already late is counted
/// in the summary's lateness.
fn pace(due: Instant, summary: &mut StandSummary) {
    let now = Instant::now();
    if due > now {
        let wait = due - now;
        if wait > Duration::from_micros(300) {
            std::thread::sleep(wait - Duration::from_micros(200));
        }
        while Instant::now() < due {
            std::hint::spin_loop();
        }
    } else {
        summary.max_lateness_s = summary.max_lateness_s.max((now - due).as_secs_f64());
    }
}

impl Faults {
    /// The stream faults applied to one sample, with the random draws always in the same
    /// order (drop, NaN, swap with the next, duplicate) so a seed replays the same faults:
    /// the samples to publish now (none, one, or two or three after a swap or duplicate).
    fn apply(
        &self,
        mut sample: SensorSample,
        rng: &mut impl Rng,
        held: &mut Option<SensorSample>,
    ) -> Vec<SensorSample> {
        let mut batch = Vec::with_capacity(3);
        if rng.random::<f64>() < self.drop_probability {
            return batch;
        }
        if rng.random::<f64>() < self.nan_probability {
            sample.force_n = f64::NAN;
        }
        if let Some(h) = held.take() {
            batch.push(sample);
            batch.push(h);
        } else if rng.random::<f64>() < self.swap_probability {
            *held = Some(sample);
        } else {
            batch.push(sample);
        }
        if rng.random::<f64>() < self.duplicate_probability {
            if let Some(&last) = batch.last() {
                batch.push(last);
            }
        }
        batch
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stream(f: &Faults, seed: u64, n: usize) -> Vec<f64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut held = None;
        (0..n)
            .flat_map(|k| {
                let s = SensorSample {
                    time_s: k as f64,
                    force_n: 1.0,
                    ..Default::default()
                };
                f.apply(s, &mut rng, &mut held)
            })
            .map(|s| {
                if s.force_n.is_nan() {
                    -s.time_s
                } else {
                    s.time_s
                }
            })
            .collect()
    }

    #[test]
    fn faults_follow_their_probabilities_and_a_seed_replays_them() {
        let none = stream(&Faults::default(), 1, 1000);
        assert_eq!(none, (0..1000).map(|k| k as f64).collect::<Vec<_>>());
        let f = Faults {
            drop_probability: 0.1,
            duplicate_probability: 0.1,
            swap_probability: 0.1,
            nan_probability: 0.1,
            ..Default::default()
        };
        let a = stream(&f, 7, 20_000);
        assert_eq!(a, stream(&f, 7, 20_000), "same seed, same faults");
        assert_ne!(a, stream(&f, 8, 20_000));
        let nan = a.iter().filter(|t| **t < 0.0).count() as f64 / a.len() as f64;
        assert!((nan - 0.1).abs() < 0.02, "NaN share {nan}");
        let back = a.windows(2).filter(|w| w[1].abs() < w[0].abs()).count();
        assert!(back > 1000, "{back} out-of-order steps");
        let dups = a.windows(2).filter(|w| w[1] == w[0]).count();
        assert!(dups > 1000, "{dups} duplicates");
        // Each sample dropped with probability 0.1 (a swapped one may come back later).
        let distinct: std::collections::BTreeSet<u64> = a.iter().map(|t| t.abs() as u64).collect();
        let dropped = 1.0 - distinct.len() as f64 / 20_000.0;
        assert!((dropped - 0.1).abs() < 0.02, "dropped {dropped}");
    }

    fn played(player: &mut StandPlayer, n: usize) -> Vec<SensorSample> {
        let mut batch = Vec::new();
        (0..n)
            .flat_map(|_| {
                player.next(&mut batch);
                batch.clone()
            })
            .collect()
    }

    #[test]
    fn a_retune_takes_effect_at_the_next_sample_and_keeps_the_clock() {
        let p = StandParams {
            noise_n: 0.0,
            ..StandParams::default()
        };
        let mut player = StandPlayer::new(&p).unwrap();
        player.set_epoch(100.0);
        let before = played(&mut player, 500);
        assert!(before.iter().all(|s| s.current_a == 0.5));
        // Same parameters: nothing restarts, the stream goes on as if untouched.
        let mut untouched = StandPlayer::new(&p).unwrap();
        untouched.set_epoch(100.0);
        let reference = played(&mut untouched, 1000);
        player.retune(&p).unwrap();
        // (compared as text: the temperature channel is NaN, not measured)
        assert_eq!(
            format!("{:?}", played(&mut player, 500)),
            format!("{:?}", &reference[500..])
        );
        // A new programme (one current) from the next sample, started at its beginning.
        let q = StandParams {
            currents_a: vec![1.75],
            ..p.clone()
        };
        player.retune(&q).unwrap();
        let after = played(&mut player, 10);
        assert!(after.iter().all(|s| s.current_a == 1.75), "{after:?}");
        assert_eq!(after[0].displacement_m, 0.0, "the programme starts at rest");
        assert!((after[0].time_s - (100.0 + 1000.0 / p.rate_hz)).abs() < 1e-9);
        // A model parameter: a 50 kN load-cell offset shows from the next sample.
        let mut r = q.clone();
        r.two_chamber.load_cell_offset_n += 50_000.0;
        let last = played(&mut player, 1)[0].force_n;
        player.retune(&r).unwrap();
        let shifted = played(&mut player, 1)[0].force_n;
        assert!(shifted - last > 40_000.0, "{last} → {shifted}");
        // The pacing and the random stream are fixed for a run.
        let fast = StandParams {
            rate_hz: 2000.0,
            ..q.clone()
        };
        assert!(player
            .retune(&fast)
            .unwrap_err()
            .to_string()
            .contains("rate_hz"));
    }
}
