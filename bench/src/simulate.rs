//! The embedded default bench: its capabilities, the simulator configuration a plan asks for,
//! and what a simulated run records of it. Runs go through [`crate::runner::run`] with
//! [`crate::runner::Bench::Simulated`] (or [`crate::runner::simulate_in_memory`]).

use bench_physics::effects::{EffectId, Effects};
use bench_sim::SimConfig;

use crate::plan::RunPlan;
use crate::scenario::Capabilities;

/// Bench time zero of simulated runs: 2026-01-01T00:00:00Z, fixed so that a run is a pure
/// function of scenario and seed.
pub const SIM_EPOCH_NS: u64 = 1_767_225_600_000_000_000;

/// The simulated bench's capabilities, for validating scenarios.
pub fn capabilities() -> Capabilities {
    let i = bench_sim::default_infos();
    Capabilities { table: i.table, chamber: i.chamber, gyro: i.gyro }
}

/// The simulator configuration a plan asks for.
pub fn sim_config(plan: &RunPlan, seed: u64) -> SimConfig {
    SimConfig {
        seed,
        gyro_model: plan.sim.truth.clone(),
        gyro_effects: plan.sim.truth_effects,
        gyro_sample_rate_hz: plan.gyro.sample_rate_hz,
        latitude_deg: plan.site.latitude_deg,
        axis_up: plan.site.axis_up(),
        initial_temp_c: plan.sim.initial_temp_c,
        ..SimConfig::default()
    }
}

/// The effects a simulated run records in `bench.gyro_model` (the contract's "model the
/// simulator used"): the nominal effects (what the lab believes, `[gyro.model.effects]`) and,
/// when the simulated table ripples and the nominal effects say nothing of it, the table's own
/// ripple as `rate_ripple` — physics the simulator simulates, so a diagnosis takes it as
/// nominal. The truth's own effects (`[simulation.truth.effects]`, a concealed `rate_ripple`
/// included) stay concealed.
pub fn recorded_effects(plan: &RunPlan, config: &SimConfig) -> Effects {
    let mut effects = plan.gyro.effects;
    let table = &config.table;
    let ripple = EffectId::RateRipple;
    if !effects.has(ripple) && table.ripple_rel > 0.0 && table.ripple_cycles_per_rev > 0 {
        let values =
            [table.ripple_rel, f64::from(table.ripple_cycles_per_rev), table.ripple_phase_rad];
        // Three values, the ripple's three parameters.
        let _ = effects.set(ripple, &values);
    }
    effects
}
