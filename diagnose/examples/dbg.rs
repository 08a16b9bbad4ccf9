use diagnose::{diagnose, Options, Signals};
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let mut s = Signals::default();
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        s.time_s.push(v[0]); s.displacement_m.push(v[1]); s.velocity_m_s.push(v[2]); s.force_n.push(v[3]); s.current_a.push(v[4]);
    }
    let mut o = Options::default();
    o.selector = diagnose::Selector::Rules;
    let dg = diagnose(&s, &path, &o).unwrap();
    let d = &dg.data;
    let mut idx: Vec<usize> = (0..d.len()).collect();
    idx.sort_by(|&a, &b| (d.weight[b].sqrt()*(d.f[b]-dg.baseline_force[b])).abs().total_cmp(&(d.weight[a].sqrt()*(d.f[a]-dg.baseline_force[a])).abs()));
    for &j in idx.iter().take(25) {
        println!("t {:.4} vmeas {:.6} vhat {:.6} i {:.2} f {:.1} model {:.1} res {:.1} w {:.3} vs {:.6}", d.t[j], d.v_meas[j], d.v[j], d.i[j], d.f[j], dg.baseline_force[j], d.f[j]-dg.baseline_force[j], d.weight[j], d.v_sigma[j]);
    }
    println!("{:?}", dg.report.baseline_parameters);
}
