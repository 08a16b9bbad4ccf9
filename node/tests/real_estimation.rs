//! The yield-stress estimator on Dyke's broadband record
//! (`../shared/data/real/dyke-nees/ransim_u.csv`): random strokes with a command voltage
//! that never holds still, a damper none of our simulators produced. The samples go
//! through the node's own conditioning ([`Conditioner`]: the command voltage becomes the
//! coil current of a unipolar driver, 1 A/V behind the 8.65 ms lag `mrtwin fit` finds on
//! the record, `cli/tests/real_records.rs`; the clipped force stretch is found stuck) and
//! reach the estimator as they do in `node::pipeline::TwinPipeline`.

use std::path::PathBuf;

use estimation::online::{
    force_per_pa, EstimatorConfig, EstimatorSample, RejectReason, YieldEstimator,
};
use node::conditioning::{Conditioner, ConditioningConfig, CurrentChannel, SensorSample};
use twin::models::{ModelKind, ModelParams};

#[test]
fn dyke_continuous_current_gives_a_physical_law_in_current() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data/real/dyke-nees/ransim_u.csv");
    let rec = bridge::csv::read_csv(&path).unwrap_or_else(|e| panic!("{e}"));
    let mut conditioner = Conditioner::new(ConditioningConfig {
        current_channel: CurrentChannel::CommandVoltage,
        driver_gain_a_per_v: 1.0,
        driver_lag_s: 0.00865,
        ..ConditioningConfig::default()
    });
    let cfg = EstimatorConfig {
        settle_time_s: 0.0,
        memory_s: 5.0,
        sqrt_velocity_term: false,
        ..Default::default()
    };
    // Nominal geometry: the rod force per pascal of the default two-chamber damper.
    let a = force_per_pa(ModelKind::TwoChamber, &ModelParams::default()).unwrap();
    let mut est = YieldEstimator::new(cfg, a);
    let mut stuck = 0;
    for s in &rec.samples {
        let Ok(admitted) = conditioner.admit(&SensorSample::from_recording(s)) else {
            continue;
        };
        let c = &admitted.sample;
        let es = EstimatorSample {
            time_s: c.time_s,
            displacement_m: c.displacement_m,
            velocity_m_s: c.velocity_m_s,
            force_n: c.force_n,
            current_a: c.current_a,
        };
        match admitted.stuck {
            Some(channel) => {
                stuck += 1;
                est.reject(&es, RejectReason::Stuck(channel));
            }
            None => {
                est.update(&es);
            }
        }
    }
    assert!(stuck > 0, "the clipped stretch was not found");
    let raw = est.raw_curve();
    let curve = est.curve();
    let report: String = raw
        .iter()
        .map(|e| {
            format!(
                "{:.3} A: {:.2} ± {:.2} kPa\n",
                e.current_a,
                e.tau0_pa / 1e3,
                e.tau0_std_pa / 1e3
            )
        })
        .collect();
    eprintln!("{report}");
    // The law covers the coil currents the record drives (0 to 2.2 A) knot by knot...
    assert!(raw.len() >= 20, "{report}");
    assert!(
        raw[0].current_a < 0.1 && raw[raw.len() - 1].current_a > 2.0,
        "{report}"
    );
    // ...every point of it is a physical yield stress before any projection...
    assert!(raw.iter().all(|e| e.tau0_pa > 0.0), "{report}");
    // ...it rises with the field, by more than 5× from the lowest to the highest current...
    assert!(
        raw[raw.len() - 1].tau0_pa > 5.0 * raw[0].tau0_pa,
        "{report}"
    );
    // ...and where it falls between neighbours it does so within 2.5 σ of their
    // difference (the law saturates above ≈ 1.4 A), so the published curve only pools
    // points that the data cannot order.
    for w in raw.windows(2) {
        let drop = w[0].tau0_pa - w[1].tau0_pa;
        let sd = w[0].tau0_std_pa.hypot(w[1].tau0_std_pa);
        assert!(
            drop < 2.5 * sd,
            "τ0 falls from {} A to {} A by {drop:.0} Pa (σ {sd:.0})\n{report}",
            w[0].current_a,
            w[1].current_a
        );
    }
    assert_eq!(curve.len(), raw.len(), "every point is identified");
    assert!(curve.windows(2).all(|w| w[1].tau0_pa >= w[0].tau0_pa));
}
