//! The machine-readable result of `bench diagnose --json FILE` (version 1, documented in
//! `docs/diagnose.md`). SI units; times in s from the recording's first message.

use bench_analysis::diagnose::{Diagnosis, Finding, Region};
use serde_json::{json, Map, Value};

use super::DiagnoseOutcome;

fn num(x: f64) -> Value {
    if x.is_finite() {
        json!(x)
    } else {
        Value::Null
    }
}

fn windows(w: &[(f64, f64)]) -> Value {
    Value::Array(w.iter().map(|(a, b)| json!([num(*a), num(*b)])).collect())
}

fn finding(f: &Finding) -> Value {
    let mut params = Map::new();
    for p in &f.parameters {
        params.insert(
            p.name.into(),
            json!({"value": num(p.value), "sigma": num(p.sigma), "unit": p.unit}),
        );
    }
    let mut v = json!({
        "effect": f.effect.key(),
        "description": f.effect.description(),
        "parameters": params,
        "evidence": {
            "delta_bic": num(f.delta_bic),
            "wald": num(f.wald),
            "wald_threshold": num(f.threshold),
            "holdout_z": num(f.holdout_z),
            "rms_before": num(f.rms_before),
            "rms_after": num(f.rms_after),
            "windows_s": windows(&f.windows_s),
        },
    });
    let Some(o) = v.as_object_mut() else { return v };
    if let Some(why) = &f.rejected_because {
        o.insert("rejected_because".into(), json!(why));
    }
    if let Some(remark) = &f.remark {
        o.insert("remark".into(), json!(remark));
    }
    if let Some(c) = &f.family {
        o.insert(
            "family_check".into(),
            json!({
                "family": c.family,
                "members": c.members,
                "passed": c.passed,
                "size_change_z": num(c.size_change_z),
                "size_change_limit": num(c.size_change_limit),
                "strongest": c.strongest.as_ref().map(|m| json!({
                    "name": m.name, "wald": num(m.wald), "threshold": num(m.threshold),
                    "size_rad_s": num(m.size_rad_s)})),
            }),
        );
    }
    if let Some(r) = &f.rate_dependence {
        o.insert(
            "rate_dependence".into(),
            json!({
                "cycles_per_rev": num(r.cycles_per_rev),
                "belongs_to": r.verdict(),
                "gyro_wald": num(r.gyro_wald),
                "ripple_wald": num(r.ripple_wald),
                "threshold": num(r.threshold),
            }),
        );
    }
    v
}

fn region(r: &Region) -> Value {
    json!({"name": r.name, "bins": r.bins, "mean": num(r.mean), "sigma": num(r.sigma),
           "z": num(r.z())})
}

fn regions(rs: &[Region]) -> Value {
    Value::Array(rs.iter().map(region).collect())
}

/// The result as JSON.
pub fn to_json(o: &DiagnoseOutcome, recording: &str) -> Value {
    let d: &Diagnosis = &o.diagnosis;
    let mut updates = Map::new();
    for u in &d.parameter_updates {
        updates.insert(
            u.key.key().into(),
            json!({"nominal": num(u.nominal), "fitted": num(u.fitted), "sigma": num(u.sigma),
                   "held": u.held}),
        );
    }
    let l = &d.location;
    json!({
        "version": 1,
        "recording": recording,
        "nominal_model": o.nominal.2,
        "verdict": d.verdict.key(),
        "verdict_caveats": super::verdict_caveats(d),
        "identifiability": d.identifiability().iter().map(|c| json!({
            "effect": c.effect.key(),
            "effect_in_model": c.effect_accepted,
            "with": c.with_name(),
            "with_terms": c.with,
            "rho": num(c.rho),
            "sigma_inflation": num(c.sigma_inflation),
            "bound": {"parameter": c.parameter, "value": num(c.bound), "unit": c.unit,
                      "confidence": 0.95},
        })).collect::<Vec<_>>(),
        "parameter_updates": updates,
        "parameters_wald": {"value": num(d.parameters_wald.value), "threshold": num(d.parameters_wald.threshold)},
        "findings": d.findings.iter().filter(|f| f.accepted).map(finding).collect::<Vec<_>>(),
        "tested": d.findings.iter().filter(|f| !f.accepted).map(finding).collect::<Vec<_>>(),
        "unexplained": d.unexplained.iter().map(|u| json!({
            "windows_s": windows(&u.windows_s),
            "correlates_with": u.correlates_with,
            "rms": num(u.rms),
        })).collect::<Vec<_>>(),
        "noise": {
            "before": {"arw": num(d.noise_before.arw), "flicker_floor": num(d.noise_before.flicker_floor),
                       "rrw": num(d.noise_before.rrw)},
            "after": {"arw": num(d.noise_after.arw), "flicker_floor": num(d.noise_after.flicker_floor),
                      "rrw": num(d.noise_after.rrw)},
            "n_eff": num(d.n_eff),
            "bins": d.n_bins,
        },
        "rms": {"nominal": num(d.rms.nominal), "refit": num(d.rms.before), "final": num(d.rms.after),
                "resimulated": o.resimulated.as_ref().map_or(Value::Null, |r| num(r.rms.nominal))},
        "bic": {"refit": num(d.bic.before), "final": num(d.bic.after)},
        "resimulated_verdict": o.resimulated.as_ref().map(|r| r.verdict.key()),
        "location": {
            "steps": regions(&l.steps),
            "direction": regions(&l.direction),
            "thermal": regions(&l.thermal),
            "temperature": regions(&l.temperature),
            "angle": regions(&l.angle),
            "transitions": l.transitions.as_ref().map_or(Value::Null, region),
            "change_point": l.change_point.map(|(t, w)| json!({"time_s": num(t), "wald": num(w)})),
            "harmonics": l.harmonics.iter().map(|(k, a, w)| json!({
                "cycles_per_rev": k, "amplitude": num(*a), "wald": num(*w)})).collect::<Vec<_>>(),
        },
        "updated_model": {
            "gyro_model": d.model.to_metadata(),
            "effects": d.effects.to_metadata(),
        },
    })
}
