//! Cost of the physics per gyro sample (budget: ≲ 100 ns for the noise at 20 Hz) and per
//! table / chamber evaluation, for one hour at 20 Hz (72 000 of each).

#![allow(missing_docs)] // criterion's macros generate undocumented items

use bench_physics::chamber::{ChamberModel, ChamberParams};
use bench_physics::gyro::{GyroSampler, Mounting};
use bench_physics::noise::GyroNoise;
use bench_physics::table::{RateTableModel, TableParams};
use bench_physics::units::{DEG, DEG_PER_MIN};
use bench_physics::GyroModel;
use criterion::{criterion_group, criterion_main, Criterion};
use rand::SeedableRng;

const N: usize = 72_000;

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("physics_one_hour_20hz");
    g.sample_size(20);
    g.bench_function("noise", |b| {
        b.iter(|| {
            let mut n = GyroNoise::from_model(&GyroModel::default(), 0.05, 1, 1);
            (0..N).map(|_| n.next_sample()).sum::<f64>()
        })
    });
    g.bench_function("gyro_table_chamber", |b| {
        b.iter(|| {
            let mut table = RateTableModel::new(TableParams::default());
            table.command_rate(0.0, 10.0 * DEG_PER_MIN, DEG).ok();
            let m = GyroModel::default();
            let mut ch = ChamberModel::new(ChamberParams::default(), 20.0, m.thermal_time_constant);
            ch.set_target(0.0, 60.0, Some(1.0 / 60.0)).ok();
            let mount = Mounting { latitude_deg: 59.94, axis_up: true };
            let mut gy = GyroSampler::new(m, 0.05, 1, 1, mount, 20.0);
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
            let mut s = 0.0;
            for k in 1..=N {
                let t = k as f64 * 0.05;
                let th = ch.state(t);
                s += gy.sample(t, table.true_angle(t), th.payload_c).total();
                let ts = table.state(t);
                s += table.readout(&ts, &mut rng).angle_rad;
                let cs = ch.state(t);
                s += ch.readout(&cs, &mut rng).temperature_c;
            }
            s
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
