use twin::models::*;
use twin::stand::*;
use twin::*;
fn run_at(rate: f64, sub: f64, eff: EffectSet, law: FluidLaw) -> Vec<(f64, f64)> {
    let prog = Programme::grid(0.01, &[5.0], &[1.0], 0.6, rate);
    let mut p = TwoChamberParams::default();
    p.max_substep_s = sub;
    p.fluid.law = law;
    let mut m = TwoChamber::new(p, eff);
    run(&mut m, &prog, None).iter().map(|s| (s.time_s, s.output.force_n)).collect()
}
fn main() {
    for law in [FluidLaw::Bingham, FluidLaw::BodnerPartom] {
    for eff in [EffectSet::paper(), EffectSet::all()] {
        let reference = run_at(64000.0, 1.0, eff, law);
        let peak = reference.iter().map(|p| p.1.abs()).fold(0.0, f64::max);
        for sub in [1e-3, 5e-4, 2.5e-4] {
            for rate in [1000.0, 2000.0, 4000.0] {
                let r = run_at(rate, sub, eff, law);
                let step = (64000.0 / rate) as usize;
                let err = r.iter().enumerate().map(|(k, p)| (p.1 - reference[k * step].1).abs()).fold(0.0, f64::max);
                let t0 = std::time::Instant::now();
                for _ in 0..3 { run_at(rate, sub, eff, law); }
                let el = t0.elapsed() / (3 * r.len() as u32);
                print!("{law:?} {eff} sub {sub:e} rate {rate}: maxerr/peak {:.2e} ({el:?}/sample)\n", err / peak);
            }
        }
    }}
}
