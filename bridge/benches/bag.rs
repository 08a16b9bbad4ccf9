//! Bag write and read throughput for `mrtwin_msgs/DamperSample`, in messages per second,
//! beside the CSV writer and reader of the same samples (the reference row).
//!
//! `cargo bench -p bridge --bench bag`

#![allow(missing_docs)] // criterion_group! generates an undocumented pub fn.

use std::path::PathBuf;

use bridge::bag::{self, BagCompression, BagWriter, BagWriterOptions};
use bridge::transport::Message;
use bridge::{Recording, Sample};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use msgs::{DamperSample, Header};

const N: usize = 20_000;

fn recording() -> Recording {
    let samples = (0..N)
        .map(|i| {
            let t = i as f64 * 1e-3;
            let w = 2.0 * std::f64::consts::PI * 1.66;
            Sample {
                time_s: t,
                displacement_m: 0.01 * (w * t).sin(),
                velocity_m_s: 0.01 * w * (w * t).cos(),
                force_n: 900.0 * (w * t).cos() + 3.0 * (i % 17) as f64,
                current_a: 1.0,
                temperature_c: Some(25.0 + 1e-4 * i as f64),
            }
        })
        .collect();
    Recording {
        samples,
        velocity_derived: false,
        has_temperature: true,
        source: "bench".into(),
    }
}

fn scratch() -> PathBuf {
    let d = std::env::temp_dir().join(format!("mrtwin-bag-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write_bag(path: &std::path::Path, rec: &Recording, compression: BagCompression) {
    let mut w = BagWriter::create(
        path,
        BagWriterOptions {
            compression,
            ..Default::default()
        },
    )
    .unwrap();
    for s in &rec.samples {
        let m = DamperSample {
            header: Header::at(s.time_s, "d1"),
            displacement: s.displacement_m,
            velocity: s.velocity_m_s,
            force: s.force_n,
            current: s.current_a,
            temperature: s.temperature_c.unwrap_or(f64::NAN),
        };
        let t = m.header.stamp.as_nanos() as u64;
        w.write_message("d1", &Message::Sample(m), t).unwrap();
    }
    w.finish().unwrap();
}

fn bench(c: &mut Criterion) {
    let rec = recording();
    let dir = scratch();
    let mut k = 0u64;
    let mut fresh = |name: &str| {
        k += 1;
        let p = dir.join(format!("{name}{k}"));
        let _ = std::fs::remove_dir_all(&p);
        let _ = std::fs::remove_file(&p);
        p
    };

    let mut g = c.benchmark_group("write_damper_samples");
    g.throughput(Throughput::Elements(N as u64));
    g.sample_size(20);
    for (name, comp) in [
        ("bag_zstd", BagCompression::Zstd),
        ("bag_uncompressed", BagCompression::None),
    ] {
        g.bench_function(BenchmarkId::from_parameter(name), |b| {
            b.iter(|| {
                let p = fresh("w");
                write_bag(&p, &rec, comp);
                std::fs::remove_dir_all(&p).unwrap();
            })
        });
    }
    g.bench_function(BenchmarkId::from_parameter("csv_reference"), |b| {
        b.iter(|| {
            let p = fresh("w").with_extension("csv");
            bridge::write_csv(&p, &rec).unwrap();
            std::fs::remove_file(&p).unwrap();
        })
    });
    g.finish();

    let zstd = dir.join("read_zstd");
    let plain = dir.join("read_plain");
    let csv = dir.join("read.csv");
    write_bag(&zstd, &rec, BagCompression::Zstd);
    write_bag(&plain, &rec, BagCompression::None);
    bridge::write_csv(&csv, &rec).unwrap();
    let mut g = c.benchmark_group("read_damper_samples");
    g.throughput(Throughput::Elements(N as u64));
    g.sample_size(20);
    g.bench_function(BenchmarkId::from_parameter("bag_zstd"), |b| {
        b.iter(|| assert_eq!(bag::read_recording(&zstd).unwrap().len(), N))
    });
    g.bench_function(BenchmarkId::from_parameter("bag_uncompressed"), |b| {
        b.iter(|| assert_eq!(bag::read_recording(&plain).unwrap().len(), N))
    });
    g.bench_function(BenchmarkId::from_parameter("csv_reference"), |b| {
        b.iter(|| assert_eq!(bridge::read_csv(&csv).unwrap().len(), N))
    });
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, bench);
criterion_main!(benches);
