use twin::models::*;
use twin::stand::*;
use twin::*;
fn run_at(rate: f64, sub: f64) -> Vec<(f64, f64, f64, f64)> {
    let prog = Programme::grid(0.01, &[5.0], &[1.0], 0.6, rate);
    let mut p = TwoChamberParams::default();
    p.max_substep_s = sub;
    let mut m = TwoChamber::new(p, EffectSet::paper());
    run(&mut m, &prog, None).iter().map(|s| (s.time_s, s.output.force_n, s.input.velocity_m_s, s.input.displacement_m)).collect()
}
fn main() {
    let reference = run_at(64000.0, 1.0);
    for sub in [1e-3, 5e-4, 2.5e-4, 1.25e-4] {
        let r = run_at(1000.0, sub);
        let (k, e) = r.iter().enumerate().map(|(k, p)| (k, (p.1 - reference[k * 64].1).abs())).fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
        println!("sub {sub:e}: max err {e:.2} N at t={:.4} (F {:.1} ref {:.1} v {:.4} x {:.5})", r[k].0, r[k].1, reference[k*64].1, r[k].2, r[k].3);
        for j in k-3..k+3 { println!("   t={:.4} F {:.1} ref {:.1}", r[j].0, r[j].1, reference[j*64].1); }
    }
}
