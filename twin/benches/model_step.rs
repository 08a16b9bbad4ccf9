//! Cost of one model step at 1 kHz for every model: `cargo bench -p twin --bench model_step`.
//!
//! Each iteration advances the model by one 1 ms sample of a 5 Hz, 10 mm stroke at 1 A,
//! cycling through a precomputed second of input. The Bingham baseline (algebraic) is the
//! reference floor measured in the same run.

#![allow(missing_docs)] // criterion_group! generates an undocumented pub fn.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::hint::black_box;
use twin::models::{
    BinghamDamper, BinghamParams, DirectShear, DirectShearParams, FluidLaw, Spencer, SpencerParams,
    TwoChamber, TwoChamberParams,
};
use twin::stand::Programme;
use twin::{DamperInput, DamperModel, EffectSet};

fn inputs() -> Vec<DamperInput> {
    let prog = Programme::grid(0.01, &[5.0], &[1.0], 1.0, 1000.0);
    (0..prog.sample_count())
        .map(|k| prog.input_at(k).2)
        .collect()
}

fn bench_model(c: &mut Criterion, name: &str, mut model: Box<dyn DamperModel>) {
    let inputs = inputs();
    model.reset(&inputs[0]);
    // One warm cycle so the loop is steady.
    for inp in &inputs {
        model.step(inp, 1e-3);
    }
    let mut group = c.benchmark_group("model_step_1kHz");
    group.throughput(Throughput::Elements(1));
    let mut k = 0;
    group.bench_function(name, |b| {
        b.iter(|| {
            k = (k + 1) % inputs.len();
            black_box(model.step(black_box(&inputs[k]), 1e-3))
        })
    });
    group.finish();
}

fn two_chamber(law: FluidLaw, effects: EffectSet) -> Box<dyn DamperModel> {
    let mut p = TwoChamberParams::default();
    p.fluid.law = law;
    if law == FluidLaw::BodnerPartom {
        p.gap_active_length_m = 0.004;
    }
    Box::new(TwoChamber::new(p, effects))
}

fn benches(c: &mut Criterion) {
    bench_model(
        c,
        "bingham (reference)",
        Box::new(BinghamDamper::new(BinghamParams::default())),
    );
    bench_model(
        c,
        "spencer",
        Box::new(Spencer::new(SpencerParams::default())),
    );
    bench_model(
        c,
        "direct-shear",
        Box::new(DirectShear::new(DirectShearParams::default())),
    );
    bench_model(
        c,
        "two-chamber incompressible (none)",
        two_chamber(FluidLaw::Bingham, EffectSet::NONE),
    );
    bench_model(
        c,
        "two-chamber paper (Bingham)",
        two_chamber(FluidLaw::Bingham, EffectSet::paper()),
    );
    bench_model(
        c,
        "two-chamber all effects (Bingham)",
        two_chamber(FluidLaw::Bingham, EffectSet::all()),
    );
    bench_model(
        c,
        "two-chamber all effects (Herschel-Bulkley)",
        two_chamber(FluidLaw::HerschelBulkley, EffectSet::all()),
    );
    bench_model(
        c,
        "two-chamber all effects (Bodner-Partom)",
        two_chamber(FluidLaw::BodnerPartom, EffectSet::all()),
    );
}

criterion_group! {
    name = model_step;
    config = Criterion::default().sample_size(30).measurement_time(std::time::Duration::from_secs(2)).warm_up_time(std::time::Duration::from_millis(500));
    targets = benches
}
criterion_main!(model_step);
