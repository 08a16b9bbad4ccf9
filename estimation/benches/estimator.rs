//! Cost per sample of the yield-stress estimator and the health monitor:
//! `cargo bench -p estimation --bench estimator`.
//!
//! Input: a precomputed second at 1 kHz of a 2 Hz, 10 mm stroke at 1 A through the default
//! two-chamber damper (paper model), with 1 % force noise. Rows, in the same run:
//! * `reference: two-chamber step` — the model step alone (the twin's own cost);
//! * `estimator update` — one `YieldEstimator::update` (the current held on one knot);
//! * `estimator update, moving current` — the same with a current sweeping 0.2–1.8 A;
//! * `estimator update + at_current` — what the node does per sample for publishing;
//! * `health observe` — one `HealthMonitor::observe`;
//! * `health checks (per publish)` — building every `Check` (once per /diagnostics message);
//! * `health level (per sample)` — the worst level alone, no message formatted;
//! * `twin + estimation + health` — model step, update, at_current and observe together.

#![allow(missing_docs)] // criterion_group! generates an undocumented pub fn.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use estimation::health::{HealthConfig, HealthMonitor, Observation};
use estimation::online::{force_per_pa, EstimatorConfig, EstimatorSample, YieldEstimator};
use std::hint::black_box;
use twin::models::{build, ModelKind, ModelParams};
use twin::stand::{run, Noise, Programme, SimulatedSample};
use twin::DamperModel;

fn record() -> Vec<SimulatedSample> {
    let prog = Programme::grid(0.01, &[2.0], &[1.0], 1.0, 1000.0);
    let mut model = build(
        ModelKind::TwoChamber,
        &ModelParams::default(),
        ModelKind::TwoChamber.default_effects(),
    )
    .unwrap();
    run(
        model.as_mut(),
        &prog,
        Some(Noise {
            fraction: 0.01,
            seed: 1,
        }),
    )
}

fn sample(s: &SimulatedSample, t: f64) -> EstimatorSample {
    EstimatorSample {
        time_s: t,
        displacement_m: s.input.displacement_m,
        velocity_m_s: s.input.velocity_m_s,
        force_n: s.measured_force_n,
        current_a: s.input.current_a,
    }
}

fn bench(c: &mut Criterion) {
    let rec = record();
    let n = rec.len();
    let params = ModelParams::default();
    let a = force_per_pa(ModelKind::TwoChamber, &params).unwrap();
    let mut g = c.benchmark_group("per_sample_1kHz");
    g.throughput(Throughput::Elements(1));

    let mut model: Box<dyn DamperModel> = build(
        ModelKind::TwoChamber,
        &params,
        ModelKind::TwoChamber.default_effects(),
    )
    .unwrap();
    model.reset(&rec[0].input);
    let mut k = 0usize;
    g.bench_function("reference: two-chamber step", |b| {
        b.iter(|| {
            k = (k + 1) % n;
            black_box(model.step(black_box(&rec[k].input), 1e-3))
        })
    });

    // Time keeps increasing across the cycled record.
    let mut est = YieldEstimator::new(EstimatorConfig::default(), a);
    let mut j = 0u64;
    g.bench_function("estimator update", |b| {
        b.iter(|| {
            j += 1;
            let s = sample(&rec[(j as usize) % n], j as f64 * 1e-3);
            black_box(est.update(black_box(&s)))
        })
    });

    // The same samples with a current that never holds still (a sweep 0.2–1.8 A, period
    // 20 s of sample time, no settling gate): every update touches two knots and solves
    // the run of ≈ 17 adjacent knots.
    let cfg = EstimatorConfig {
        settle_time_s: 0.0,
        ..EstimatorConfig::default()
    };
    let mut est = YieldEstimator::new(cfg, a);
    let mut j = 0u64;
    g.bench_function("estimator update, moving current", |b| {
        b.iter(|| {
            j += 1;
            let t = j as f64 * 1e-3;
            let s = EstimatorSample {
                current_a: 1.0 - 0.8 * (2.0 * std::f64::consts::PI * t / 20.0).cos(),
                ..sample(&rec[(j as usize) % n], t)
            };
            black_box(est.update(black_box(&s)))
        })
    });

    let mut est = YieldEstimator::new(EstimatorConfig::default(), a);
    let mut j = 0u64;
    g.bench_function("estimator update + at_current", |b| {
        b.iter(|| {
            j += 1;
            let s = sample(&rec[(j as usize) % n], j as f64 * 1e-3);
            est.update(black_box(&s));
            black_box(est.at_current(s.current_a))
        })
    });

    let mut health = HealthMonitor::new(HealthConfig::default());
    let mut j = 0u64;
    g.bench_function("health observe", |b| {
        b.iter(|| {
            j += 1;
            let s = &rec[(j as usize) % n];
            health.observe(black_box(&Observation {
                time_s: j as f64 * 1e-3,
                force_n: s.measured_force_n,
                predicted_force_n: s.output.force_n,
                current_a: 1.0,
                dissipated_power_w: s.output.dissipated_power_w,
                fluid_temperature_c: 25.0,
                ambient_temperature_c: 25.0,
                estimate: None,
                rejected: false,
                stuck_channel: None,
                gas_preload_pa: None,
            }))
        })
    });

    // Reading every check (the string formatting a /diagnostics publish pays), on the
    // monitor filled above.
    g.bench_function("health checks (per publish)", |b| {
        b.iter(|| black_box(health.checks()))
    });
    g.bench_function("health level (per sample)", |b| {
        b.iter(|| black_box(black_box(&health).level()))
    });

    let mut est = YieldEstimator::new(EstimatorConfig::default(), a);
    let mut health = HealthMonitor::new(HealthConfig::default());
    model.reset(&rec[0].input);
    let mut j = 0u64;
    g.bench_function("twin + estimation + health", |b| {
        b.iter(|| {
            j += 1;
            let s = &rec[(j as usize) % n];
            let out = model.step(&s.input, 1e-3);
            let es = sample(s, j as f64 * 1e-3);
            let outcome = est.update(&es);
            let estimate = est.at_current(es.current_a);
            health.observe(&Observation {
                time_s: es.time_s,
                force_n: es.force_n,
                predicted_force_n: out.force_n,
                current_a: es.current_a,
                dissipated_power_w: out.dissipated_power_w,
                fluid_temperature_c: out.fluid_temperature_c,
                ambient_temperature_c: 25.0,
                estimate,
                rejected: matches!(outcome, estimation::UpdateOutcome::Rejected(_)),
                stuck_channel: None,
                gas_preload_pa: None,
            });
            black_box(estimate)
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
