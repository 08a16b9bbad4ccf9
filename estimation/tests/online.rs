//! The online yield-stress estimator and the health monitor on simulated truth.
//!
//! Simulator: the Bingham-type damper F = a τ_y(I) sgn v + c(I) v + f0
//! (`twin::models::BinghamDamper`) sized as the default two-chamber damper: a from
//! [`force_per_pa`] of its geometry (2 L A1/h), τ_y(I) from its fluid's quadratic
//! (`TwoChamberParams::default().fluid.yield_stress_pa`), f0 = −p0 Ar its gas preload.
//! The truth τ0 is that quadratic, never anything the estimator computed.

use estimation::health::{HealthConfig, HealthMonitor, Level, Observation};
use estimation::online::{
    force_per_pa, EstimatorConfig, EstimatorSample, Tau0Estimate, UpdateOutcome, YieldEstimator,
};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use twin::models::{
    polynomial_in_current, quadratic_in_current, BinghamDamper, BinghamParams, ModelKind,
    ModelParams,
};
use twin::stand::Programme;
use twin::DamperModel;

struct Truth {
    a: f64,
    tau_y: [f64; 3],
    params: BinghamParams,
}

impl Truth {
    fn new() -> Self {
        let mp = ModelParams::default();
        let a = force_per_pa(ModelKind::TwoChamber, &mp).unwrap();
        let tc = &mp.two_chamber;
        let tau_y: [f64; 3] = tc
            .fluid
            .yield_stress_pa
            .clone()
            .try_into()
            .expect("the default fluid's τ_y is a quadratic");
        Self {
            a,
            tau_y,
            params: BinghamParams {
                friction_force_n: tau_y.map(|c| c * a),
                offset_n: -tc.gas_preload_pa * tc.rod_area(),
                ..BinghamParams::default()
            },
        }
    }
    fn tau0(&self, i: f64) -> f64 {
        quadratic_in_current(&self.tau_y, i)
    }
    /// The damper with its yield stress scaled by `factor`.
    fn model(&self, factor: f64) -> BinghamDamper {
        let mut p = self.params.clone();
        p.friction_force_n = p.friction_force_n.map(|c| c * factor);
        BinghamDamper::new(p)
    }
}

/// 2 Hz, 10 mm stroke, current cycling 0.5 → 1 → 2 A every `every_s` seconds, 1 kHz.
fn programme(every_s: f64, cycles: usize) -> Programme {
    duty(0.010, 2.0, every_s, cycles)
}

/// `amplitude_m` at `frequency_hz`, current cycling 0.5 → 1 → 2 A every `every_s` seconds.
fn duty(amplitude_m: f64, frequency_hz: f64, every_s: f64, cycles: usize) -> Programme {
    let mut p = Programme::grid(
        amplitude_m,
        &[frequency_hz],
        &[0.5, 1.0, 2.0],
        every_s,
        1000.0,
    );
    let one = p.segments.clone();
    for _ in 1..cycles {
        p.segments.extend_from_slice(&one);
    }
    p
}

const NOISE_N: f64 = 15.0; // ≈ 1 % of the peak force

struct Step {
    t: f64,
    current: f64,
    sample: EstimatorSample,
    predicted: f64,
    power: f64,
}

/// Drive the truth (yield stress scaled by `factor(t)`) and the nominal model through the
/// programme; force noise N(0, NOISE_N²).
fn stream(
    truth: &Truth,
    prog: &Programme,
    seed: u64,
    factor: impl Fn(f64) -> f64,
    mut each: impl FnMut(&Step),
) {
    let mut nominal = truth.model(1.0);
    let mut weak_models = [truth.model(1.0), truth.model(1.0)];
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let normal = Normal::new(0.0, NOISE_N).unwrap();
    let dt = 1.0 / prog.rate_hz;
    for k in 0..prog.sample_count() {
        let (_, t, input) = prog.input_at(k);
        let f = factor(t);
        let real = if f == 1.0 {
            &mut weak_models[0]
        } else {
            weak_models[1] = truth.model(f);
            &mut weak_models[1]
        };
        let out = real.step(&input, dt);
        let pred = nominal.step(&input, dt);
        each(&Step {
            t,
            current: input.current_a,
            sample: EstimatorSample {
                time_s: t,
                displacement_m: input.displacement_m,
                velocity_m_s: input.velocity_m_s,
                force_n: out.force_n + normal.sample(&mut rng),
                current_a: input.current_a,
            },
            predicted: pred.force_n,
            power: pred.dissipated_power_w,
        });
    }
}

#[test]
fn converges_within_five_percent_in_two_seconds_at_each_current() {
    let truth = Truth::new();
    let prog = programme(3.0, 2);
    let mut est = YieldEstimator::new(EstimatorConfig::default(), truth.a);
    let mut entered: Option<(f64, f64)> = None; // (current, time it was entered)
    let mut checked = 0;
    let mut report = String::new();
    stream(
        &truth,
        &prog,
        1,
        |_| 1.0,
        |s| {
            if entered.is_none_or(|(i, _)| i != s.current) {
                entered = Some((s.current, s.t));
            }
            est.update(&s.sample);
            let (i, t0) = entered.unwrap();
            // 2 s after entering the current (every visit, the first from a flat prior).
            if (s.t - t0 - 2.0).abs() < 0.5e-3 {
                let e = est.at_current(i).expect("an estimate after 2 s");
                let rel = e.tau0_pa / truth.tau0(i) - 1.0;
                report.push_str(&format!(
                    "t {:.1} s, {i} A: tau0 {:.0} ± {:.0} Pa, truth {:.0} Pa ({:+.2} %)\n",
                    s.t,
                    e.tau0_pa,
                    e.tau0_std_pa,
                    truth.tau0(i),
                    100.0 * rel
                ));
                assert!(rel.abs() < 0.05, "{report}");
                checked += 1;
            }
        },
    );
    eprintln!("{report}");
    assert_eq!(checked, 6);
    let curve = est.curve();
    assert_eq!(curve.len(), 3);
    assert!(curve.windows(2).all(|w| w[1].tau0_pa > w[0].tau0_pa));
    // Between bins, at_current interpolates along the curve.
    let mid = est.at_current(0.75).unwrap();
    assert!(mid.tau0_pa > curve[0].tau0_pa && mid.tau0_pa < curve[1].tau0_pa);
    // Gas preload from the offset.
    let (f0, f0_sd) = est.force_offset_n().unwrap();
    assert!(
        (f0 - truth.params.offset_n).abs() < 4.0 * f0_sd + 1.0,
        "{f0} ± {f0_sd}"
    );
}

/// The flow-mode damper of the second paper (compressible chambers, gas spring, Bingham
/// fluid in the gap): its force is not linear in sgn v (Buckingham–Reiner flow, z-loop), and
/// the truth is the fluid's τ_y(I) of the simulator's parameters.
#[test]
fn converges_on_the_two_chamber_damper_of_the_second_paper() {
    let mp = ModelParams::default();
    let a = force_per_pa(ModelKind::TwoChamber, &mp).unwrap();
    let mut model = twin::models::build(
        ModelKind::TwoChamber,
        &mp,
        ModelKind::TwoChamber.default_effects(),
    )
    .unwrap();
    let prog = programme(3.0, 2);
    let out = twin::stand::run(
        model.as_mut(),
        &prog,
        Some(twin::stand::Noise {
            fraction: 0.01,
            seed: 5,
        }),
    );
    let truth = |i: f64| polynomial_in_current(&mp.two_chamber.fluid.yield_stress_pa, i);
    let mut est = YieldEstimator::new(EstimatorConfig::default(), a);
    let mut entered = (f64::NAN, 0.0);
    let mut report = String::new();
    let mut checked = 0;
    for s in &out {
        let i = s.input.current_a;
        if i != entered.0 {
            entered = (i, s.time_s);
        }
        est.update(&EstimatorSample {
            time_s: s.time_s,
            displacement_m: s.input.displacement_m,
            velocity_m_s: s.input.velocity_m_s,
            force_n: s.measured_force_n,
            current_a: i,
        });
        if (s.time_s - entered.1 - 2.0).abs() < 0.5e-3 {
            let e = est.at_current(i).expect("an estimate after 2 s");
            let rel = e.tau0_pa / truth(i) - 1.0;
            report.push_str(&format!(
                "t {:.1} s, {i} A: tau0 {:.0} ± {:.0} Pa, truth {:.0} Pa ({:+.2} %)\n",
                s.time_s,
                e.tau0_pa,
                e.tau0_std_pa,
                truth(i),
                100.0 * rel
            ));
            assert!(rel.abs() < 0.05, "{report}");
            checked += 1;
        }
    }
    eprintln!("{report}");
    assert_eq!(checked, 6);
}

#[test]
fn reported_standard_deviation_covers_the_truth_as_often_as_it_claims() {
    let truth = Truth::new();
    let prog = programme(3.0, 1);
    let mut z = Vec::new();
    for seed in 0..60 {
        // The regression's statistical σ (and the structure part, ≈ 0 here): the data are
        // its own model, so the model-form part (the spread between the √ and the plain
        // Bingham intercepts, issue 13) would only widen it; it is measured where the
        // model is wrong, on the proving ground (BENCHMARKS.md).
        // Nor the common-offset part (a seal friction the regression reads as yield: here
        // there is none, and its bound, the curve's zero-current intercept, only widens).
        let cfg = EstimatorConfig {
            model_form_share: 0.0,
            common_offset_share: 0.0,
            ..Default::default()
        };
        let mut est = YieldEstimator::new(cfg, truth.a);
        let mut last_current = None;
        stream(
            &truth,
            &prog,
            100 + seed,
            |_| 1.0,
            |s| {
                // At the end of each current's segment.
                if last_current.is_some_and(|i| i != s.current) {
                    let i = last_current.unwrap();
                    let e = est.at_current(i).unwrap();
                    z.push((e.tau0_pa - truth.tau0(i)) / e.tau0_std_pa);
                }
                est.update(&s.sample);
                last_current = Some(s.current);
            },
        );
        let e = est.at_current(2.0).unwrap();
        z.push((e.tau0_pa - truth.tau0(2.0)) / e.tau0_std_pa);
    }
    let frac = |k: f64| z.iter().filter(|v| v.abs() < k).count() as f64 / z.len() as f64;
    let (one, two) = (frac(1.0), frac(2.0));
    eprintln!(
        "{} estimates: |z|<1 {:.3} (68.3 %), |z|<2 {:.3} (95.4 %)",
        z.len(),
        one,
        two
    );
    // 180 draws: the fractions' standard deviations are 0.035 and 0.016.
    assert!((one - 0.683).abs() < 0.11, "|z|<1 in {one}");
    assert!((two - 0.954).abs() < 0.05, "|z|<2 in {two}");
}

fn health_config(truth: &Truth) -> HealthConfig {
    HealthConfig {
        force_noise_std_n: NOISE_N,
        tau0_reference: [0.5, 1.0, 2.0].map(|i| (i, truth.tau0(i))).to_vec(),
        nominal_rate_hz: Some(1000.0),
        ..Default::default()
    }
}

fn observe(est: &mut YieldEstimator, health: &mut HealthMonitor, s: &Step) -> UpdateOutcome {
    let outcome = est.update(&s.sample);
    health.observe(&Observation {
        time_s: s.sample.time_s,
        force_n: s.sample.force_n,
        predicted_force_n: s.predicted,
        current_a: s.current,
        dissipated_power_w: s.power,
        fluid_temperature_c: 25.0,
        ambient_temperature_c: 25.0,
        estimate: est.at_current(s.current),
        rejected: matches!(outcome, UpdateOutcome::Rejected(_)),
        stuck_channel: None,
        gas_preload_pa: None,
    });
    outcome
}

#[test]
fn twenty_percent_loss_of_yield_stress_is_flagged_within_five_seconds() {
    let truth = Truth::new();
    let prog = programme(3.0, 3);
    let t_loss = 12.0;
    let mut est = YieldEstimator::new(EstimatorConfig::default(), truth.a);
    let mut health = HealthMonitor::new(health_config(&truth));
    let mut flagged: Option<f64> = None;
    let mut tau_flagged: Option<f64> = None;
    let mut last_est = None;
    stream(
        &truth,
        &prog,
        7,
        |t| if t < t_loss { 1.0 } else { 0.8 },
        |s| {
            observe(&mut est, &mut health, s);
            if s.sample.time_s.rem_euclid(0.1) < 1e-3 {
                let checks = health.checks();
                let level = checks.iter().map(|c| c.level).max().unwrap();
                if s.t < t_loss {
                    assert!(s.t < 1.0 || level == Level::Ok, "t {}: {checks:?}", s.t);
                } else {
                    if flagged.is_none() && level >= Level::Warn {
                        flagged = Some(s.t);
                    }
                    let y = checks.iter().find(|c| c.name == "yield stress").unwrap();
                    if tau_flagged.is_none() && y.level >= Level::Warn {
                        tau_flagged = Some(s.t);
                    }
                }
            }
            last_est = est.at_current(s.current).map(|e| (s.current, e));
        },
    );
    let flagged = flagged.expect("loss never flagged");
    let tau_flagged = tau_flagged.expect("yield-stress check never flagged");
    eprintln!("loss at {t_loss} s: health WARN at {flagged:.1} s, yield-stress WARN at {tau_flagged:.1} s");
    assert!(flagged - t_loss <= 5.0);
    assert!(tau_flagged - t_loss <= 5.0);
    // The estimate followed the weakened fluid.
    let (i, e) = last_est.unwrap();
    let rel = e.tau0_pa / (0.8 * truth.tau0(i)) - 1.0;
    assert!(rel.abs() < 0.05, "{i} A: {e:?} vs {}", 0.8 * truth.tau0(i));
}

#[test]
fn ten_minute_nominal_run_at_one_kilohertz_raises_no_warning() {
    let truth = Truth::new();
    // A duty the damper sustains: 5 mm at 1 Hz dissipates ≈ 25 W on average, a lumped
    // temperature rise of ≈ 17 K (the 10 mm, 2 Hz programme of the other tests dissipates
    // ≈ 165 W, which over 10 minutes would heat the damper by ~100 K and rightly raise
    // the thermal check).
    let prog = duty(0.005, 1.0, 4.0, 50); // 600 s
    assert_eq!(prog.sample_count(), 600_000);
    let mut est = YieldEstimator::new(EstimatorConfig::default(), truth.a);
    let mut health = HealthMonitor::new(health_config(&truth));
    let mut worst = Level::Ok;
    let mut worst_checks = Vec::new();
    stream(
        &truth,
        &prog,
        11,
        |_| 1.0,
        |s| {
            observe(&mut est, &mut health, s);
            if s.t > 1.0 && s.sample.time_s.rem_euclid(0.05) < 1e-3 {
                let level = health.level();
                if level > worst {
                    worst = level;
                    worst_checks = health.checks();
                }
            }
        },
    );
    assert_eq!(worst, Level::Ok, "{worst_checks:#?}");
    assert_eq!(est.rejected_count(), 0);
}

#[test]
fn bad_data_is_rejected_counted_and_reported_without_corrupting_the_estimate() {
    let truth = Truth::new();
    let prog = programme(3.0, 2);
    let cfg = EstimatorConfig {
        force_saturation_n: Some(5000.0),
        ..Default::default()
    };
    let mut est = YieldEstimator::new(cfg, truth.a);
    let mut health = HealthMonitor::new(health_config(&truth));
    let mut injected = 0;
    let mut data_warned = false;
    let mut before = None;
    stream(
        &truth,
        &prog,
        3,
        |_| 1.0,
        |s| {
            let k = (s.t * 1000.0).round() as u64;
            let mut step = Step { ..*s };
            let mut drop = false;
            if (13_000..13_500).contains(&k) {
                // A burst: NaN, saturated, infinite and stuck-at-limit forces.
                step.sample.force_n = match k % 4 {
                    0 => f64::NAN,
                    1 => 5000.0,
                    2 => f64::NEG_INFINITY,
                    _ => -7000.0,
                };
                injected += 1;
            } else if (14_000..14_300).contains(&k) {
                drop = true; // 0.3 s dropout: the sensor sends nothing
            } else if k == 14_300 {
                injected += 1; // first sample after the dropout is rejected
            }
            if k == 12_999 {
                before = est.at_current(s.current);
            }
            if !drop {
                let outcome = observe(&mut est, &mut health, &step);
                let expected = (13_000..13_500).contains(&k) || k == 14_300;
                assert_eq!(
                    matches!(outcome, UpdateOutcome::Rejected(_)),
                    expected,
                    "{k}: {outcome:?}"
                );
                if k == 13_400 {
                    let dq = health
                        .checks()
                        .into_iter()
                        .find(|c| c.name == "data quality")
                        .unwrap();
                    data_warned = dq.level >= Level::Warn;
                }
                if k == 14_350 {
                    let sr = health
                        .checks()
                        .into_iter()
                        .find(|c| c.name == "sample rate")
                        .unwrap();
                    assert!(sr.level >= Level::Warn, "{sr:?}");
                }
            }
            if k == 13_500 {
                let after = est.at_current(s.current).unwrap();
                let b = before.unwrap();
                assert!(after.tau0_pa.is_finite() && after.tau0_std_pa.is_finite());
                // Bad samples did not move the estimate beyond the change of 0.5 s of good data.
                assert!(
                    (after.tau0_pa / b.tau0_pa - 1.0).abs() < 0.03,
                    "{b:?} -> {after:?}"
                );
            }
        },
    );
    assert!(data_warned, "health did not report the rejected samples");
    assert_eq!(est.rejected_count(), injected);
    for e in est.curve() {
        let rel = e.tau0_pa / truth.tau0(e.current_a) - 1.0;
        assert!(rel.abs() < 0.05, "{e:?}");
    }
}

/// A current that never holds still: a slow sweep 0.1 → 1.9 A and back (period 40 s)
/// with a faster wobble of ±0.15 A, the stroke 10 mm at 2 Hz, 1 kHz, noise 15 N, for 80 s.
/// The law on knots 0.1 A apart is checked against the truth's τ0 at every point of the
/// curve: within 3 σ (and 3 % from 0.1 A up), with |z| < 2 at 85 % of them or more, and
/// the curve rising with current without any pooling (the raw law is already monotone).
#[test]
fn a_continuously_moving_current_gives_a_smooth_law_that_follows_the_truth() {
    let truth = Truth::new();
    let cfg = EstimatorConfig {
        settle_time_s: 0.0,
        memory_s: 10.0,
        ..Default::default()
    };
    let mut est = YieldEstimator::new(cfg, truth.a);
    let mut model = truth.model(1.0);
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let normal = Normal::new(0.0, NOISE_N).unwrap();
    // The stroke of an 80 s segment; its current is replaced sample by sample.
    let stroke = Programme::grid(0.010, &[2.0], &[1.0], 80.0, 1000.0);
    let dt = 1.0 / stroke.rate_hz;
    for k in 0..stroke.sample_count() {
        let (_, t, held) = stroke.input_at(k);
        let sweep = 1.0 - 0.9 * (2.0 * std::f64::consts::PI * t / 40.0).cos();
        let current_a = sweep + 0.15 * (2.0 * std::f64::consts::PI * 0.37 * t).sin();
        let input = twin::DamperInput { current_a, ..held };
        let f = model.step(&input, if k == 0 { 0.0 } else { dt }).force_n;
        est.update(&EstimatorSample {
            time_s: t,
            displacement_m: input.displacement_m,
            velocity_m_s: input.velocity_m_s,
            force_n: f + normal.sample(&mut rng),
            current_a,
        });
    }
    let raw = est.raw_curve();
    let curve = est.curve();
    let mut report = String::new();
    let mut within2 = 0;
    for e in &curve {
        let t = truth.tau0(e.current_a);
        let z = (e.tau0_pa - t) / e.tau0_std_pa;
        report.push_str(&format!(
            "{:.3} A: {:.0} ± {:.0} Pa, truth {:.0} ({:+.2} %, z {:+.2})\n",
            e.current_a,
            e.tau0_pa,
            e.tau0_std_pa,
            t,
            100.0 * (e.tau0_pa / t - 1.0),
            z
        ));
        within2 += usize::from(z.abs() < 2.0);
    }
    eprintln!("{report}");
    for e in &curve {
        let t = truth.tau0(e.current_a);
        // Below 0.1 A only the rim of the wobble reaches: 3σ alone there.
        assert!(
            e.current_a < 0.1 || (e.tau0_pa / t - 1.0).abs() < 0.03,
            "{report}"
        );
        assert!(((e.tau0_pa - t) / e.tau0_std_pa).abs() < 3.0, "{report}");
    }
    // Knots from 0 to 2.1 A: every knot the sweep covers gives a point.
    assert!(curve.len() >= 18, "{report}");
    assert!(
        within2 as f64 >= 0.85 * curve.len() as f64,
        "{within2} of {} within 2σ\n{report}",
        curve.len()
    );
    // No pooling: the same points and τ0, and σ differs from the raw law's only by the
    // common-offset widening, one amount added in quadrature to every point (its own
    // model-error part included).
    let points = |c: &[Tau0Estimate]| {
        c.iter()
            .map(|e| (e.current_a, e.tau0_pa))
            .collect::<Vec<_>>()
    };
    assert_eq!(
        points(&raw),
        points(&curve),
        "the raw law needed pooling\n{report}"
    );
    let added = curve[0].tau0_std_pa.powi(2) - raw[0].tau0_std_pa.powi(2);
    for (r, c) in raw.iter().zip(&curve) {
        for (w, u) in [
            (c.tau0_std_pa, r.tau0_std_pa),
            (c.model_std_pa, r.model_std_pa),
        ] {
            let extra = w * w - u * u;
            assert!(
                extra >= 0.0 && (extra - added).abs() <= 1e-9 * (w * w).max(1.0),
                "σ of the curve is not the raw law's plus one common offset: {r:?} / {c:?}\n{report}"
            );
        }
    }
    assert!(curve.windows(2).all(|w| w[1].tau0_pa > w[0].tau0_pa));
}
