//! Replay throughput: samples per second through the twin pipeline (conditioning, model,
//! yield-stress estimator, health), per model, next to the bare model step on the same
//! samples as the reference.
//!
//! `cargo bench -p node --bench replay`

#![allow(missing_docs)] // criterion_group! generates an undocumented pub fn.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use node::conditioning::SensorSample;
use node::pipeline::{PipelineConfig, TwinPipeline};
use twin::models::{build, ModelKind, ModelParams};
use twin::stand::{run, Noise, Programme};
use twin::EffectSet;

fn samples(kind: ModelKind, effects: EffectSet) -> Vec<SensorSample> {
    let prog = Programme::grid(0.01, &[1.0, 2.0, 4.0], &[0.5, 1.0, 2.0], 1.0, 1000.0);
    let mut m = build(kind, &ModelParams::default(), effects).unwrap();
    run(
        m.as_mut(),
        &prog,
        Some(Noise {
            fraction: 0.01,
            seed: 3,
        }),
    )
    .iter()
    .map(SensorSample::from)
    .collect()
}

fn replay(c: &mut Criterion) {
    let cases = [
        ("direct-shear", ModelKind::DirectShear, EffectSet::NONE),
        (
            "two-chamber paper",
            ModelKind::TwoChamber,
            EffectSet::paper(),
        ),
        ("bingham", ModelKind::Bingham, EffectSet::NONE),
    ];
    let mut g = c.benchmark_group("replay");
    for (name, kind, effects) in cases {
        let data = samples(kind, effects);
        g.throughput(Throughput::Elements(data.len() as u64));
        g.bench_with_input(BenchmarkId::new("pipeline", name), &data, |b, data| {
            b.iter(|| {
                let mut p = TwinPipeline::new(PipelineConfig {
                    model: kind,
                    effects,
                    ..Default::default()
                })
                .unwrap();
                let mut acc = 0.0;
                for s in data {
                    if let node::pipeline::Processed::Stepped(st) = p.process(s) {
                        acc += st.residual_n;
                    }
                }
                acc
            })
        });
        g.bench_with_input(
            BenchmarkId::new("model step only (reference)", name),
            &data,
            |b, data| {
                b.iter(|| {
                    let mut m = build(kind, &ModelParams::default(), effects).unwrap();
                    let mut acc = 0.0;
                    let mut prev = data[0].time_s;
                    for (k, s) in data.iter().enumerate() {
                        let input = twin::DamperInput {
                            displacement_m: s.displacement_m,
                            velocity_m_s: s.velocity_m_s,
                            acceleration_m_s2: 0.0,
                            current_a: s.current_a,
                            ambient_temperature_c: 25.0,
                        };
                        if k == 0 {
                            m.reset(&input);
                        }
                        acc += m.step(&input, s.time_s - prev).force_n;
                        prev = s.time_s;
                    }
                    acc
                })
            },
        );
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = replay
}
criterion_main!(benches);
