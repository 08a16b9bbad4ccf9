use twin::models::*;
use twin::stand::*;
use twin::*;
fn main() {
    let prog = Programme::grid(0.01, &[5.0], &[1.0], 1.0, 1000.0);
    for (name, eff, k) in [("paper", EffectSet::paper(), 5e8), ("none", EffectSet::NONE, 5e8), ("K=1e12", EffectSet::paper(), 1e12), ("all", EffectSet::all(), 5e8)] {
        let mut p = TwoChamberParams::default();
        p.bulk_modulus_pa = k;
        let mut m = TwoChamber::new(p, eff);
        let t0 = std::time::Instant::now();
        let s = run(&mut m, &prog, None);
        let el = t0.elapsed();
        let last: Vec<_> = s.iter().filter(|s| s.time_s >= 0.6).collect();
        let x: Vec<f64> = last.iter().map(|s| s.input.displacement_m).collect();
        let v: Vec<f64> = last.iter().map(|s| s.input.velocity_m_s).collect();
        let f: Vec<f64> = last.iter().map(|s| s.output.force_n).collect();
        let w = metrics::loop_work(&x, &f);
        let e = last.last().unwrap().output.dissipated_energy_j - last[0].output.dissipated_energy_j;
        let fmax = f.iter().cloned().fold(f64::MIN, f64::max);
        let fmin = f.iter().cloned().fold(f64::MAX, f64::min);
        println!("{name}: F [{fmin:.1},{fmax:.1}] loop {w:.3} J diss {e:.3} J zgap {:.4}  {:?}/sample", metrics::zero_force_velocity_gap(&v,&f), el / s.len() as u32);
    }
}
