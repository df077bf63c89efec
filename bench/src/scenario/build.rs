//! From the spanned TOML tree to a validated [`RunPlan`]: strict key checking, units, loop
//! expansion and checks against the devices' capabilities. Errors are collected, never thrown.

use std::collections::HashSet;
use std::ops::Range;
use std::time::Duration;

use bench_physics::effects::{EffectId, Effects};
use bench_physics::{gyro_model::GYRO_MODEL_KEYS, GyroModel, ModelKey};

use super::quantity::{self, fmt_num, Dim, Quantity};
use super::Capabilities;
use crate::plan::{
    Action, GyroSetup, PlannedStep, RunPlan, SimSetup, Station, TempSource, ACCEPTANCE_KEYS,
    STATION_KEYS,
};
use bench_recording::message::is_record_label;
use bench_recording::toml_doc::{line_col, Entry, Node, Value};
use bench_recording::{Axis, Site, SiteNumber};

/// Largest number of steps a scenario may expand to.
pub(crate) const MAX_STEPS: usize = 100_000;

/// Longest duration accepted anywhere (a year), s; keeps `Duration` conversions finite.
const MAX_DURATION_S: f64 = 365.0 * 86_400.0;

/// The action keys of a step, canonical names.
const ACTIONS: [&str; 7] = ["chamber", "spin", "stop", "wait", "wait_temperature", "record", "for"];

/// The error was reported; the caller uses a default and goes on.
struct Reported;

type Got<T> = Result<Option<T>, Reported>;

/// A table of the tree with its span.
#[derive(Clone, Copy)]
struct Tbl<'a> {
    entries: &'a [Entry],
    span: &'a Range<usize>,
}

impl<'a> Tbl<'a> {
    fn get(&self, key: &str) -> Option<&'a Entry> {
        self.entries.iter().find(|e| e.key == key)
    }
}

/// State carried along the expanded steps.
struct State {
    /// The chamber's target after the steps so far, °C.
    setpoint_c: f64,
    /// Where the latest ramp started, °C.
    ramp_from_c: f64,
    /// A ramp was started and nothing has waited for its end yet.
    ramp_active: bool,
    /// Nominal length of the latest ramp, s.
    ramp_duration_s: f64,
    /// Expansion was cut at [`MAX_STEPS`].
    overflow: bool,
}

/// `[safe]`: where an abort leaves the bench.
struct Safe {
    decel_rad_s2: f64,
    temp_c: f64,
    chamber_hold: bool,
}

struct Builder<'a> {
    text: &'a str,
    source: &'a str,
    caps: &'a Capabilities,
    /// (span, message, loop context) — context is appended when reported.
    issues: Vec<(Range<usize>, String, String)>,
    seen: HashSet<(usize, String)>,
    /// Loop variables in scope, outermost first.
    vars: Vec<(String, String)>,
    steps: Vec<PlannedStep>,
    /// Defaults from the settings sections.
    table_accel: f64,
    /// `[interlocks]`, as far as parsed (commands are checked against them).
    interlocks: crate::plan::Interlocks,
}

/// Build the plan, or return every issue as (span, message).
pub(crate) fn build(
    root: &Node,
    text: &str,
    source: &str,
    caps: &Capabilities,
) -> Result<RunPlan, Vec<(Range<usize>, String)>> {
    let mut b = Builder {
        text,
        source,
        caps,
        issues: Vec::new(),
        seen: HashSet::new(),
        vars: Vec::new(),
        steps: Vec::new(),
        table_accel: 10.0 * bench_physics::units::DEG,
        interlocks: crate::plan::Interlocks::defaults(caps),
    };
    let plan = b.root(root);
    if b.issues.is_empty() {
        if let Some(plan) = plan {
            return Ok(plan);
        }
    }
    Err(b
        .issues
        .into_iter()
        .map(|(span, msg, ctx)| (span, if ctx.is_empty() { msg } else { format!("{msg} ({ctx})") }))
        .collect())
}

impl<'a> Builder<'a> {
    fn err(&mut self, span: &Range<usize>, msg: impl Into<String>) -> Reported {
        let msg = msg.into();
        // The same mistake inside a loop body is reported once, with its first iteration.
        if self.seen.insert((span.start, msg.clone())) {
            let ctx =
                self.vars.iter().map(|(k, v)| format!("{k} = {v}")).collect::<Vec<_>>().join(", ");
            let ctx = if ctx.is_empty() { ctx } else { format!("in loop: {ctx}") };
            self.issues.push((span.clone(), msg, ctx));
        }
        Reported
    }

    fn origin(&self, span: &Range<usize>) -> String {
        let (l, c) = line_col(self.text, span.start);
        format!("{}:{l}:{c}", self.source)
    }

    // ---------------------------------------------------------------- generic readers

    /// Report keys of `t` not in `allowed`.
    fn check_keys(&mut self, t: Tbl<'_>, allowed: &[&str], what: &str) {
        for e in t.entries {
            if !allowed.contains(&e.key.as_str()) {
                let hint = closest(&e.key, allowed)
                    .map(|k| format!("did you mean `{k}`? "))
                    .unwrap_or_default();
                self.err(
                    &e.key_span,
                    format!(
                        "unknown key `{}` in {what}; {hint}allowed: {}",
                        e.key,
                        allowed.iter().map(|k| format!("`{k}`")).collect::<Vec<_>>().join(", ")
                    ),
                );
            }
        }
    }

    /// A sub-table (`[site]`); `None` if absent.
    fn table(&mut self, t: Tbl<'a>, key: &str) -> Got<Tbl<'a>> {
        let Some(e) = t.get(key) else { return Ok(None) };
        match &e.node.value {
            Value::Table(entries) => Ok(Some(Tbl { entries, span: &e.node.span })),
            v => {
                Err(self
                    .err(&e.node.span, format!("`{key}` must be a table, got {}", v.type_name())))
            }
        }
    }

    /// Substitute loop variables into a string value.
    fn subst(&mut self, s: &str, span: &Range<usize>) -> Result<String, Reported> {
        match substitute(s, &self.vars) {
            Ok(x) => Ok(x),
            Err(m) => Err(self.err(span, m)),
        }
    }

    /// A string (loop variables substituted).
    fn string(&mut self, t: Tbl<'_>, key: &str) -> Got<(String, Range<usize>)> {
        let Some(e) = t.get(key) else { return Ok(None) };
        match &e.node.value {
            Value::Str(s) => {
                let s = self.subst(s, &e.node.span)?;
                Ok(Some((s, e.node.span.clone())))
            }
            v => {
                Err(self
                    .err(&e.node.span, format!("`{key}` must be a string, got {}", v.type_name())))
            }
        }
    }

    /// A plain finite number.
    fn number(&mut self, t: Tbl<'_>, key: &str) -> Got<(f64, Range<usize>)> {
        let Some(e) = t.get(key) else { return Ok(None) };
        match &e.node.value {
            Value::Num(x) if x.is_finite() => Ok(Some((*x, e.node.span.clone()))),
            Value::Num(_) => {
                Err(self.err(&e.node.span, format!("`{key}` must be a finite number")))
            }
            v => {
                Err(self
                    .err(&e.node.span, format!("`{key}` must be a number, got {}", v.type_name())))
            }
        }
    }

    fn boolean(&mut self, t: Tbl<'_>, key: &str) -> Got<bool> {
        let Some(e) = t.get(key) else { return Ok(None) };
        match &e.node.value {
            Value::Bool(b) => Ok(Some(*b)),
            v => Err(self.err(
                &e.node.span,
                format!("`{key}` must be true or false, got {}", v.type_name()),
            )),
        }
    }

    /// A quantity: `key = "<number> <unit>"` or `key_<si> = <number>` (not both).
    fn quantity(&mut self, t: Tbl<'_>, key: &str, dim: Dim) -> Got<(Quantity, Range<usize>)> {
        let si_key = format!("{key}_{}", dim.si_suffix());
        let with_unit = t.get(key);
        let plain = t.get(&si_key);
        if let (Some(_), Some(p)) = (with_unit, plain) {
            return Err(
                self.err(&p.key_span, format!("give either `{key}` or `{si_key}`, not both"))
            );
        }
        if let Some(e) = with_unit {
            return match &e.node.value {
                Value::Str(s) => {
                    let s = self.subst(s, &e.node.span)?;
                    match quantity::parse(&s, dim) {
                        Ok(q) => Ok(Some((q, e.node.span.clone()))),
                        Err(m) => Err(self.err(&e.node.span, format!("`{key}`: {m}"))),
                    }
                }
                Value::Num(x) => Err(self.err(
                    &e.node.span,
                    format!(
                        "`{key}` takes a quantity with a unit, like {} (units: {}); for a plain \
                         number in {} write `{si_key} = {}`",
                        dim.example(),
                        dim.accepted().join(", "),
                        Quantity::si(dim, 0.0).unit,
                        fmt_num(*x)
                    ),
                )),
                v => Err(self.err(
                    &e.node.span,
                    format!(
                        "`{key}` must be a string like {}, got {}",
                        dim.example(),
                        v.type_name()
                    ),
                )),
            };
        }
        if let Some(e) = plain {
            let unit = Quantity::si(dim, 0.0).unit;
            return match &e.node.value {
                Value::Num(x) if x.is_finite() => {
                    Ok(Some((Quantity::si(dim, *x), e.node.span.clone())))
                }
                Value::Num(_) => {
                    Err(self.err(&e.node.span, format!("`{si_key}` must be a finite number")))
                }
                v => Err(self.err(
                    &e.node.span,
                    format!(
                        "`{si_key}` takes a plain number in {unit}, got {}; for units write \
                         `{key} = {}`",
                        v.type_name(),
                        dim.example()
                    ),
                )),
            };
        }
        Ok(None)
    }

    /// A quantity that must be > 0 (and, for times, at most a year).
    fn positive(
        &mut self,
        t: Tbl<'_>,
        key: &str,
        dim: Dim,
        what: &str,
    ) -> Got<(Quantity, Range<usize>)> {
        let Some((q, span)) = self.quantity(t, key, dim)? else {
            return Ok(None);
        };
        if q.si <= 0.0 {
            return Err(
                self.err(&span, format!("{what} must be greater than zero, got {}", q.show_self()))
            );
        }
        if dim == Dim::Time && q.si > MAX_DURATION_S {
            return Err(self.err(&span, format!("{what} {} is longer than a year", q.show_self())));
        }
        Ok(Some((q, span)))
    }

    fn duration(
        &mut self,
        t: Tbl<'_>,
        key: &str,
        what: &str,
    ) -> Got<(Duration, Range<usize>, Quantity)> {
        Ok(self
            .positive(t, key, Dim::Time, what)?
            .map(|(q, span)| (Duration::from_secs_f64(q.si), span, q)))
    }

    fn required<T>(&mut self, got: Got<T>, span: &Range<usize>, msg: &str) -> Option<T> {
        match got {
            Ok(Some(x)) => Some(x),
            Ok(None) => {
                self.err(span, msg.to_string());
                None
            }
            Err(Reported) => None,
        }
    }

    // ---------------------------------------------------------------- capability checks

    /// A temperature the chamber is asked to reach: within the chamber's and gyro's ranges.
    fn check_temp(&mut self, q: &Quantity, span: &Range<usize>, what: &str) -> bool {
        let (glo, ghi) = self.caps.gyro.capabilities.operating_temp_c;
        let c = &self.caps.chamber.capabilities;
        let (clo, chi) = (c.min_temp_c, c.max_temp_c);
        if !(glo..=ghi).contains(&q.si) {
            self.err(
                span,
                format!(
                    "{what} {} is outside the gyro's operating range {}..{} °C",
                    q.show_self(),
                    fmt_num(glo),
                    fmt_num(ghi)
                ),
            );
            false
        } else if !(clo..=chi).contains(&q.si) {
            self.err(
                span,
                format!(
                    "{what} {} is outside the chamber's range {}..{} °C",
                    q.show_self(),
                    fmt_num(clo),
                    fmt_num(chi)
                ),
            );
            false
        } else if !(self.interlocks.chamber_min_temp_c..=self.interlocks.chamber_max_temp_c)
            .contains(&q.si)
        {
            self.err(
                span,
                format!(
                    "{what} {} is outside [interlocks] chamber_min_temp..chamber_max_temp {}..{} \
                     °C",
                    q.show_self(),
                    fmt_num(self.interlocks.chamber_min_temp_c),
                    fmt_num(self.interlocks.chamber_max_temp_c)
                ),
            );
            false
        } else {
            true
        }
    }

    /// `[interlocks]`: thresholds of the run-time interlocks, each a quantity (or its SI
    /// plain-number key).
    fn interlocks_section(&mut self, t: Tbl<'_>) {
        const KEYS: &[&str] = &[
            "table_max_rate",
            "table_max_rate_rad_s",
            "rate_tolerance",
            "rate_tolerance_rad_s",
            "rate_disagreement_for",
            "rate_disagreement_for_s",
            "chamber_max_temp",
            "chamber_max_temp_c",
            "chamber_min_temp",
            "chamber_min_temp_c",
            "setpoint_tolerance",
            "setpoint_tolerance_c",
            "setpoint_not_tracked_for",
            "setpoint_not_tracked_for_s",
            "gyro_status_for",
            "gyro_status_for_s",
        ];
        self.check_keys(t, KEYS, "[interlocks]");
        let positive = |b: &mut Self, q: &Quantity, span: &Range<usize>, key: &str| -> bool {
            if q.si > 0.0 && q.si.is_finite() {
                true
            } else {
                b.err(span, format!("{key} must be greater than zero, got {}", q.show_self()));
                false
            }
        };
        let tcap = self.caps.table.capabilities.max_rate_rad_s;
        if let Ok(Some((q, span))) = self.quantity(t, "table_max_rate", Dim::AngularRate) {
            if positive(self, &q, &span, "table_max_rate") {
                if q.si > tcap {
                    self.err(
                        &span,
                        format!(
                            "table_max_rate {} exceeds the table's maximum {}",
                            q.show_self(),
                            q.show(tcap)
                        ),
                    );
                } else {
                    self.interlocks.table_max_rate_rad_s = q.si;
                }
            }
        }
        if let Ok(Some((q, span))) = self.quantity(t, "rate_tolerance", Dim::AngularRate) {
            if positive(self, &q, &span, "rate_tolerance") {
                self.interlocks.rate_tolerance_rad_s = q.si;
            }
        }
        for (key, slot) in
            [("rate_disagreement_for", 0), ("setpoint_not_tracked_for", 1), ("gyro_status_for", 2)]
        {
            if let Ok(Some((q, span))) = self.quantity(t, key, Dim::Time) {
                if positive(self, &q, &span, key) {
                    let d = Duration::from_secs_f64(q.si.min(1e9));
                    match slot {
                        0 => self.interlocks.rate_disagreement_for = d,
                        1 => self.interlocks.setpoint_not_tracked_for = d,
                        _ => self.interlocks.gyro_status_for = d,
                    }
                }
            }
        }
        let c = &self.caps.chamber.capabilities;
        let (clo, chi) = (c.min_temp_c, c.max_temp_c);
        for (key, max) in [("chamber_max_temp", true), ("chamber_min_temp", false)] {
            if let Ok(Some((q, span))) = self.quantity(t, key, Dim::Temperature) {
                if !(clo..=chi).contains(&q.si) {
                    self.err(
                        &span,
                        format!(
                            "{key} {} is outside the chamber's range {}..{} °C",
                            q.show_self(),
                            fmt_num(clo),
                            fmt_num(chi)
                        ),
                    );
                } else if max {
                    self.interlocks.chamber_max_temp_c = q.si;
                } else {
                    self.interlocks.chamber_min_temp_c = q.si;
                }
            }
        }
        if self.interlocks.chamber_min_temp_c >= self.interlocks.chamber_max_temp_c {
            self.err(
                t.span,
                format!(
                    "[interlocks] chamber_min_temp {} °C must be below chamber_max_temp {} °C",
                    fmt_num(self.interlocks.chamber_min_temp_c),
                    fmt_num(self.interlocks.chamber_max_temp_c)
                ),
            );
        }
        if let Ok(Some((q, span))) = self.quantity(t, "setpoint_tolerance", Dim::TempDifference) {
            if positive(self, &q, &span, "setpoint_tolerance") {
                self.interlocks.setpoint_tolerance_c = q.si;
            }
        }
    }

    /// A table acceleration: > 0 and within the table's maximum.
    fn check_accel(&mut self, q: &Quantity, span: &Range<usize>, what: &str) {
        let max = self.caps.table.capabilities.max_accel_rad_s2;
        if q.si <= 0.0 {
            self.err(span, format!("{what} must be greater than zero, got {}", q.show_self()));
        } else if q.si > max {
            self.err(
                span,
                format!("{what} {} exceeds the table's maximum {}", q.show_self(), q.show(max)),
            );
        }
    }

    /// A poll rate: > 0 Hz.
    fn poll_rate(&mut self, t: Option<Tbl<'_>>, what: &str) -> f64 {
        let Some(t) = t else { return 20.0 };
        match self.positive(t, "poll_rate", Dim::Frequency, what) {
            Ok(Some((q, _))) => q.si,
            _ => 20.0,
        }
    }

    // ---------------------------------------------------------------- sections

    fn root(&mut self, root: &'a Node) -> Option<RunPlan> {
        let Value::Table(entries) = &root.value else {
            return None;
        };
        let top = Tbl { entries, span: &root.span };
        self.check_keys(
            top,
            &[
                "scenario",
                "site",
                "gyro",
                "table",
                "chamber",
                "safe",
                "interlocks",
                "simulation",
                "station",
                "acceptance",
                "recording",
                "step",
            ],
            "the scenario file",
        );
        let name = self.scenario_section(top);
        let site = self.site_section(top);
        let table_t = self.table(top, "table").unwrap_or(None);
        if let Some(t) = table_t {
            self.check_keys(t, &["poll_rate", "poll_rate_hz", "accel", "accel_rad_s2"], "[table]");
            if let Ok(Some((q, span))) = self.quantity(t, "accel", Dim::AngularAccel) {
                self.check_accel(&q, &span, "default table acceleration");
                self.table_accel = q.si;
            }
        }
        let table_poll_hz = self.poll_rate(table_t, "table poll rate");
        let chamber_t = self.table(top, "chamber").unwrap_or(None);
        if let Some(t) = chamber_t {
            self.check_keys(t, &["poll_rate", "poll_rate_hz"], "[chamber]");
        }
        let chamber_poll_hz = self.poll_rate(chamber_t, "chamber poll rate");
        let gyro = self.gyro_section(top);
        let sim = self.simulation_section(top, &gyro);
        if let Ok(Some(t)) = self.table(top, "interlocks") {
            self.interlocks_section(t);
        }
        let safe = self.safe_section(top);
        let station = self.station_sections(top);
        let flush_interval = self.recording_section(top);
        self.steps_section(top, sim.initial_temp_c);
        Some(RunPlan {
            name,
            text: self.text.to_string(),
            source: self.source.to_string(),
            site,
            gyro,
            table_poll_hz,
            chamber_poll_hz,
            sim,
            safe_decel_rad_s2: safe.decel_rad_s2,
            safe_temp_c: safe.temp_c,
            safe_chamber_hold: safe.chamber_hold,
            interlocks: self.interlocks.clone(),
            station,
            flush_interval,
            steps: std::mem::take(&mut self.steps),
        })
    }

    /// `[scenario]`: the run's name.
    fn scenario_section(&mut self, top: Tbl<'a>) -> String {
        let mut name = String::new();
        match self.table(top, "scenario") {
            Ok(Some(t)) => {
                self.check_keys(t, &["name", "description"], "[scenario]");
                let got = self.string(t, "name");
                if let Some((n, span)) = self.required(got, t.span, "[scenario] needs `name`") {
                    if n.trim().is_empty() {
                        self.err(&span, "scenario name must not be empty");
                    }
                    name = n;
                }
                let _ = self.string(t, "description");
            }
            Ok(None) => {
                self.err(&(0..0), "missing [scenario] section with `name`");
            }
            Err(Reported) => {}
        }
        name
    }

    /// `[site]`, required (the Earth's rate needs the latitude).
    fn site_section(&mut self, top: Tbl<'a>) -> Site {
        match self.table(top, "site") {
            Ok(Some(t)) => return self.site(t),
            Ok(None) => {
                self.err(
                    &(0..0),
                    "missing [site] section with `latitude_deg` (needed for Earth rate)",
                );
            }
            Err(Reported) => {}
        }
        Site { latitude_deg: 0.0, longitude_deg: None, height_m: None, axis: Some(Axis::Up) }
    }

    /// `[gyro]`: sample rate (checked against the gyro's, the default 20 Hz too) and model.
    fn gyro_section(&mut self, top: Tbl<'a>) -> GyroSetup {
        let mut gyro = GyroSetup {
            sample_rate_hz: 20.0,
            model: GyroModel::default(),
            model_given: false,
            effects: Effects::default(),
        };
        let gyro_t = self.table(top, "gyro");
        let mut rate_checked = gyro_t.is_err();
        if let Ok(Some(t)) = gyro_t {
            self.check_keys(t, &["sample_rate", "sample_rate_hz", "model"], "[gyro]");
            match self.positive(t, "sample_rate", Dim::Frequency, "gyro sample rate") {
                Ok(Some((q, span))) => {
                    gyro.sample_rate_hz = q.si;
                    self.check_sample_rate(&q, &span);
                    rate_checked = true;
                }
                Ok(None) => {}
                Err(Reported) => rate_checked = true,
            }
            if let Ok(Some(m)) = self.table(t, "model") {
                self.model(m, &mut gyro.model, &mut gyro.effects, "[gyro.model]");
                gyro.model_given = true;
            }
        }
        if !rate_checked {
            // The default 20 Hz must be offered too.
            let q = Quantity::si(Dim::Frequency, 20.0);
            self.check_sample_rate(&q, &(0..0));
        }
        gyro
    }

    /// `[simulation]`: the start temperature and the simulated gyro's truth (the nominal
    /// model unless given).
    fn simulation_section(&mut self, top: Tbl<'a>, gyro: &GyroSetup) -> SimSetup {
        let mut sim = SimSetup {
            initial_temp_c: 20.0,
            truth: gyro.model.clone(),
            truth_effects: gyro.effects,
        };
        if let Ok(Some(t)) = self.table(top, "simulation") {
            self.check_keys(t, &["initial_temp", "initial_temp_c", "truth"], "[simulation]");
            if let Ok(Some((q, span))) = self.quantity(t, "initial_temp", Dim::Temperature) {
                if self.check_temp(&q, &span, "initial temperature") {
                    sim.initial_temp_c = q.si;
                }
            }
            if let Ok(Some(m)) = self.table(t, "truth") {
                self.model(m, &mut sim.truth, &mut sim.truth_effects, "[simulation.truth]");
            }
        }
        sim
    }

    /// `[safe]`: where an abort leaves the bench; the defaults must fit the devices too.
    fn safe_section(&mut self, top: Tbl<'a>) -> Safe {
        let mut safe = Safe {
            decel_rad_s2: 10.0 * bench_physics::units::DEG,
            temp_c: 20.0,
            chamber_hold: false,
        };
        if let Ok(Some(t)) = self.table(top, "safe") {
            self.check_keys(
                t,
                &["decel", "decel_rad_s2", "temperature", "temperature_c", "chamber_hold"],
                "[safe]",
            );
            if let Ok(Some(hold)) = self.boolean(t, "chamber_hold") {
                safe.chamber_hold = hold;
            }
            if let Ok(Some((q, span))) = self.quantity(t, "decel", Dim::AngularAccel) {
                self.check_accel(&q, &span, "safe-state deceleration");
                safe.decel_rad_s2 = q.si;
            }
            if let Ok(Some((q, span))) = self.quantity(t, "temperature", Dim::Temperature) {
                self.check_temp(&q, &span, "safe-state temperature");
                safe.temp_c = q.si;
            }
        } else {
            let a = Quantity {
                si: safe.decel_rad_s2,
                unit: "°/s²".into(),
                factor: bench_physics::units::DEG,
            };
            self.check_accel(&a, &(0..0), "default safe-state deceleration");
            let t = Quantity::si(Dim::Temperature, safe.temp_c);
            self.check_temp(&t, &(0..0), "default safe-state temperature");
        }
        safe
    }

    /// `[station]` (free text for the report) and `[acceptance]` (positive limits).
    fn station_sections(&mut self, top: Tbl<'a>) -> Station {
        let mut station = Station::default();
        if let Ok(Some(t)) = self.table(top, "station") {
            self.check_keys(t, STATION_KEYS, "[station]");
            for key in STATION_KEYS {
                if let Ok(Some((v, _))) = self.string(t, key) {
                    station.info.insert((*key).to_string(), v);
                }
            }
        }
        if let Ok(Some(t)) = self.table(top, "acceptance") {
            self.check_keys(t, ACCEPTANCE_KEYS, "[acceptance]");
            for key in ACCEPTANCE_KEYS {
                if let Ok(Some((v, span))) = self.number(t, key) {
                    if v > 0.0 {
                        station.acceptance.insert((*key).to_string(), v);
                    } else {
                        self.err(
                            &span,
                            format!("`{key}` is a limit on the coefficient's magnitude: it must be positive, got {v}"),
                        );
                    }
                }
            }
        }
        station
    }

    /// `[recording]`: the flush interval, at most 1 h.
    fn recording_section(&mut self, top: Tbl<'a>) -> Option<Duration> {
        let Ok(Some(t)) = self.table(top, "recording") else { return None };
        self.check_keys(t, &["flush_interval", "flush_interval_s"], "[recording]");
        let Ok(Some((d, span, q))) =
            self.duration(t, "flush_interval", "[recording] flush_interval")
        else {
            return None;
        };
        if d > Duration::from_secs(3600) {
            self.err(
                &span,
                format!(
                    "[recording] flush_interval {} is longer than 1 h: a kill could lose that \
                     much of the run",
                    q.show_self()
                ),
            );
            return None;
        }
        Some(d)
    }

    /// `[[step]]`: expanded into `self.steps`, the chamber starting at `initial_temp_c`.
    fn steps_section(&mut self, top: Tbl<'a>, initial_temp_c: f64) {
        let mut st = State {
            setpoint_c: initial_temp_c,
            ramp_from_c: initial_temp_c,
            ramp_active: false,
            ramp_duration_s: 0.0,
            overflow: false,
        };
        match top.get("step") {
            Some(e) => {
                self.steps_array(&e.node, "step", &mut st);
                if self.steps.is_empty() && self.issues.is_empty() {
                    self.err(&e.key_span, "the scenario has no steps");
                }
            }
            None => {
                self.err(&(0..0), "the scenario has no steps: add [[step]] tables");
            }
        }
    }

    fn site(&mut self, t: Tbl<'_>) -> Site {
        self.check_keys(t, &["latitude_deg", "longitude_deg", "height_m", "axis"], "[site]");
        let mut site =
            Site { latitude_deg: 0.0, longitude_deg: None, height_m: None, axis: Some(Axis::Up) };
        let got = self.number(t, "latitude_deg");
        if let Some((lat, span)) =
            self.required(got, t.span, "[site] needs `latitude_deg` (degrees, north positive)")
        {
            if let Err(problem) = SiteNumber::LATITUDE_DEG.check(lat) {
                self.err(&span, problem);
            }
            site.latitude_deg = lat;
        }
        if let Ok(Some((lon, span))) = self.number(t, "longitude_deg") {
            if let Err(problem) = SiteNumber::LONGITUDE_DEG.check(lon) {
                self.err(&span, problem);
            }
            site.longitude_deg = Some(lon);
        }
        if let Ok(Some((h, span))) = self.number(t, "height_m") {
            if let Err(problem) = SiteNumber::HEIGHT_M.check(h) {
                self.err(&span, problem);
            }
            site.height_m = Some(h);
        }
        if let Ok(Some((axis, span))) = self.string(t, "axis") {
            match Axis::parse(&axis) {
                Ok(a) => site.axis = Some(a),
                Err(problem) => {
                    self.err(&span, problem);
                }
            }
        }
        site
    }

    fn check_sample_rate(&mut self, q: &Quantity, span: &Range<usize>) {
        let offered = &self.caps.gyro.capabilities.sample_rates_hz;
        if !offered.iter().any(|r| (r - q.si).abs() <= 1e-9 * r.abs().max(1.0)) {
            let list = offered.iter().map(|r| fmt_num(*r)).collect::<Vec<_>>().join(", ");
            self.err(
                span,
                format!(
                    "gyro sample rate {} is not offered by the gyro; it offers {list} Hz",
                    q.show_self()
                ),
            );
        }
    }

    /// `[gyro.model]` / `[simulation.truth]`: contract key names, SI numbers, over `model`;
    /// its `effects` table over `effects`.
    fn model(&mut self, t: Tbl<'a>, model: &mut GyroModel, effects: &mut Effects, what: &str) {
        let mut allowed = GYRO_MODEL_KEYS.to_vec();
        allowed.push("effects");
        self.check_keys(t, &allowed, what);
        if let Ok(Some(et)) = self.table(t, "effects") {
            self.effects(et, effects, &format!("{}.effects]", what.trim_end_matches(']')));
        }
        for e in t.entries {
            let Some(key) = ModelKey::from_key(&e.key) else { continue };
            if key == ModelKey::EarthRate {
                match &e.node.value {
                    Value::Bool(b) => model.earth_rate = *b,
                    Value::Num(x) if *x == 0.0 || *x == 1.0 => model.earth_rate = *x == 1.0,
                    _ => {
                        self.err(&e.node.span, "`earth_rate` must be true/false (or 1/0)");
                    }
                }
                continue;
            }
            let name = key.key();
            let x = match &e.node.value {
                Value::Num(x) if x.is_finite() => *x,
                _ => {
                    self.err(
                        &e.node.span,
                        format!("`{name}` must be a finite number in the contract's SI unit"),
                    );
                    continue;
                }
            };
            if let Err(why) = key.check(x) {
                self.err(&e.node.span, format!("`{name}` {why}, got {}", fmt_num(x)));
                continue;
            }
            model.set(key, x);
        }
    }

    /// `[….effects]`: one entry per effect id over `effects`; `earth_rate = true/false`, every
    /// other effect a table of its parameters (SI, units in the names) or `false` to switch off
    /// an effect inherited from the nominal model.
    fn effects(&mut self, t: Tbl<'_>, effects: &mut Effects, what: &str) {
        let ids: Vec<&str> = EffectId::ALL.iter().map(|id| id.key()).collect();
        for e in t.entries {
            if EffectId::from_key(&e.key).is_none() {
                let hint = closest(&e.key, &ids)
                    .map(|k| format!("did you mean `{k}`? "))
                    .unwrap_or_default();
                self.err(
                    &e.key_span,
                    format!(
                        "unknown effect `{}` in {what}; {hint}known effects: {}",
                        e.key,
                        ids.iter().map(|k| format!("`{k}`")).collect::<Vec<_>>().join(", ")
                    ),
                );
            }
        }
        for e in t.entries {
            let Some(id) = EffectId::from_key(&e.key) else { continue };
            let key = id.key();
            let params = id.param_names();
            // An effect without parameters is switched on or off.
            let flag = params.is_empty();
            match &e.node.value {
                Value::Bool(true) if flag => {
                    // No parameters: the count fits.
                    let _ = effects.set(id, &[]);
                }
                Value::Bool(false) => effects.clear(id),
                Value::Table(entries) if !flag => {
                    let pt = Tbl { entries, span: &e.node.span };
                    self.check_keys(pt, &params, &format!("effect `{key}`"));
                    let mut values = Vec::with_capacity(params.len());
                    for &p in &params {
                        let got = self.number(pt, p);
                        let msg = format!(
                            "effect `{key}` needs `{p}`; its parameters: {}",
                            params.join(", ")
                        );
                        let Some((x, span)) = self.required(got, &e.node.span, &msg) else {
                            continue;
                        };
                        if id.param_must_be_positive(p) && x <= 0.0 {
                            self.err(
                                &span,
                                format!(
                                    "`{p}` of effect `{key}` must be greater than zero, got {}",
                                    fmt_num(x)
                                ),
                            );
                            continue;
                        }
                        values.push(x);
                    }
                    if values.len() == params.len() {
                        // The count was just checked.
                        let _ = effects.set(id, &values);
                    }
                }
                v if flag => {
                    self.err(
                        &e.node.span,
                        format!("effect `{key}` must be true or false, got {}", v.type_name()),
                    );
                }
                v => {
                    let example =
                        params.iter().map(|p| format!("{p} = …")).collect::<Vec<_>>().join(", ");
                    self.err(
                        &e.node.span,
                        format!(
                            "effect `{key}` must be a table of its parameters, like `{key} = \
                             {{ {example} }}`, or false to switch it off; got {}",
                            v.type_name()
                        ),
                    );
                }
            }
        }
    }

    // ---------------------------------------------------------------- steps

    fn steps_array(&mut self, node: &Node, key: &str, st: &mut State) {
        let Value::Array(items) = &node.value else {
            self.err(
                &node.span,
                format!(
                    "`{key}` must be an array of tables ({}), got {}",
                    if key == "do" { "[[step.do]]" } else { "[[step]]" },
                    node.value.type_name()
                ),
            );
            return;
        };
        for item in items {
            if st.overflow {
                return;
            }
            match &item.value {
                Value::Table(entries) => self.step(Tbl { entries, span: &item.span }, st),
                v => {
                    self.err(
                        &item.span,
                        format!("each step must be a table, got {}", v.type_name()),
                    );
                }
            }
        }
    }

    fn push(
        &mut self,
        st: &mut State,
        name: &str,
        label: String,
        at: &Range<usize>,
        action: Action,
    ) {
        if self.steps.len() >= MAX_STEPS {
            if !st.overflow {
                st.overflow = true;
                self.err(at, format!("the scenario expands to more than {MAX_STEPS} steps"));
            }
            return;
        }
        let origin = self.origin(at);
        let index = self.steps.len();
        self.steps.push(PlannedStep { index, name: name.to_string(), label, origin, action });
    }

    fn step(&mut self, t: Tbl<'_>, st: &mut State) {
        // Which action?
        let mut found: Vec<(&str, &Entry)> = Vec::new();
        for e in t.entries {
            let canon = ACTIONS.iter().copied().find(|a| {
                e.key == *a
                    || e.key
                        .strip_prefix(a)
                        .and_then(|r| r.strip_prefix('_'))
                        .is_some_and(|s| action_si_suffix(a) == Some(s))
            });
            if let Some(c) = canon {
                if !found.iter().any(|(f, _)| *f == c) {
                    found.push((c, e));
                }
            }
        }
        let Some(&(action, action_entry)) = found.first() else {
            // A misspelt action (`spn = "10 °/min"`): named at its key, with the action meant.
            let typo = t.entries.iter().find_map(|e| {
                (!NOT_ACTIONS.contains(&e.key.as_str()))
                    .then(|| closest(&e.key, &ACTIONS).map(|a| (e, a)))
                    .flatten()
            });
            if let Some((e, meant)) = typo {
                self.err(
                    &e.key_span,
                    format!(
                        "unknown key `{}` in a step; did you mean `{meant}`? (a step needs one \
                         action: `chamber`, `spin`, `stop`, `wait`, `wait_temperature`, \
                         `record` or `for`)",
                        e.key
                    ),
                );
                return;
            }
            self.err(
                t.span,
                "step has no action: give one of `chamber`, `spin`, `stop`, `wait`, \
                 `wait_temperature`, `record` or `for`",
            );
            return;
        };
        if let Some((second, e)) = found.get(1) {
            self.err(
                &e.key_span,
                format!("one action per step: this step has both `{action}` and `{second}`"),
            );
            return;
        }
        let at = action_entry.key_span.clone();

        let label = match self.string(t, "label") {
            Ok(Some((l, span))) => Some((l, span)),
            _ => None,
        };
        if action != "record" {
            if let Some((l, span)) = &label {
                if is_record_label(l) {
                    self.err(
                        span,
                        format!(
                            "label \"{l}\" starts with `record`, which marks a calibration window; \
                             only `record` steps may have such labels"
                        ),
                    );
                }
            }
        }
        let label_text = label.as_ref().map(|(l, _)| l.clone()).unwrap_or_default();

        match action {
            "chamber" => self.chamber_step(t, st, label_text, &at),
            "spin" => self.spin_step(t, st, label_text, &at),
            "stop" => self.stop_step(t, st, label_text, &at),
            "wait" => self.wait_step(t, st, label_text, &at),
            "wait_temperature" => self.wait_temp_step(t, st, label_text, &at),
            "record" => self.record_step(t, st, label, &at),
            _ => self.for_step(t, st, action_entry),
        }
    }

    fn chamber_step(&mut self, t: Tbl<'_>, st: &mut State, label: String, at: &Range<usize>) {
        self.check_keys(
            t,
            &["chamber", "chamber_c", "ramp", "ramp_c_s", "label"],
            "a `chamber` step",
        );
        // Whatever is wrong with this step, later steps see a ramp started (no cascade of
        // "no ramp" errors).
        st.ramp_active = true;
        let Ok(Some((target, tspan))) = self.quantity(t, "chamber", Dim::Temperature) else {
            return;
        };
        let ok = self.check_temp(&target, &tspan, "chamber target");
        let c = &self.caps.chamber.capabilities;
        let (heat, cool) = (c.max_heat_rate_c_s, c.max_cool_rate_c_s);
        let from = st.setpoint_c;
        let heating = target.si > from;
        let mut ramp_c_s = None;
        match self.quantity(t, "ramp", Dim::TempRate) {
            Ok(Some((r, rspan))) => {
                if r.si <= 0.0 {
                    self.err(
                        &rspan,
                        format!("ramp must be greater than zero, got {}", r.show_self()),
                    );
                } else if target.si != from {
                    let (max, word) = if heating { (heat, "heating") } else { (cool, "cooling") };
                    if r.si > max {
                        self.err(
                            &rspan,
                            format!(
                                "chamber ramp {} ({word} from {} to {} °C) exceeds the chamber's \
                                 maximum {word} rate {}",
                                r.show_self(),
                                fmt_num(from),
                                fmt_num(target.si),
                                r.show(max)
                            ),
                        );
                    }
                }
                ramp_c_s = Some(r.si);
            }
            Ok(None) => {}
            Err(Reported) => {}
        }
        let rate = ramp_c_s.unwrap_or(if heating { heat } else { cool });
        st.ramp_duration_s =
            if rate > 0.0 && rate.is_finite() { (target.si - from).abs() / rate } else { 0.0 };
        st.ramp_from_c = from;
        st.setpoint_c = target.si;
        if !ok {
            return;
        }
        self.push(st, "chamber", label, at, Action::Chamber { target_c: target.si, ramp_c_s });
    }

    fn spin_step(&mut self, t: Tbl<'_>, st: &mut State, label: String, at: &Range<usize>) {
        self.check_keys(
            t,
            &["spin", "spin_rad_s", "direction", "accel", "accel_rad_s2", "settle", "label"],
            "a `spin` step",
        );
        let rate = self.quantity(t, "spin", Dim::AngularRate);
        let dir = self.string(t, "direction");
        let accel = self.quantity(t, "accel", Dim::AngularAccel);
        let settle = self.boolean(t, "settle");
        let Ok(Some((rate, rspan))) = rate else {
            return;
        };
        let mut bad = false;
        if rate.si < 0.0 {
            self.err(
                &rspan,
                format!("give the rate's magnitude and set `direction`, got {}", rate.show_self()),
            );
            bad = true;
        }
        let tcap = &self.caps.table.capabilities;
        let (tmax, gmax) = (tcap.max_rate_rad_s, self.caps.gyro.capabilities.max_rate_rad_s);
        if rate.si.abs() > tmax {
            self.err(
                &rspan,
                format!(
                    "table rate {} exceeds the table's maximum {}",
                    rate.show_self(),
                    rate.show(tmax)
                ),
            );
            bad = true;
        } else if rate.si.abs() > gmax {
            self.err(
                &rspan,
                format!(
                    "table rate {} exceeds the gyro's input range {}",
                    rate.show_self(),
                    rate.show(gmax)
                ),
            );
            bad = true;
        } else if rate.si.abs() > self.interlocks.table_max_rate_rad_s {
            self.err(
                &rspan,
                format!(
                    "table rate {} exceeds [interlocks] table_max_rate {}",
                    rate.show_self(),
                    rate.show(self.interlocks.table_max_rate_rad_s)
                ),
            );
            bad = true;
        }
        let sign = match dir {
            Ok(Some((d, span))) => match d.to_ascii_lowercase().as_str() {
                "cw" => -1.0,
                "ccw" => 1.0,
                _ => {
                    self.err(&span, format!("direction must be \"cw\" or \"ccw\", got \"{d}\""));
                    return;
                }
            },
            Ok(None) => {
                if rate.si != 0.0 {
                    self.err(
                        at,
                        "a spin needs `direction = \"cw\"` (clockwise seen from above, negative \
                         rate) or `\"ccw\"`",
                    );
                    return;
                }
                1.0
            }
            Err(Reported) => return,
        };
        let accel_rad_s2 = match accel {
            Ok(Some((a, span))) => {
                self.check_accel(&a, &span, "table acceleration");
                a.si
            }
            Ok(None) => self.table_accel,
            Err(Reported) => return,
        };
        if bad {
            return;
        }
        let settle = settle.ok().flatten().unwrap_or(true);
        self.push(
            st,
            "table",
            label,
            at,
            Action::Table { rate_rad_s: sign * rate.si, accel_rad_s2, settle },
        );
    }

    fn stop_step(&mut self, t: Tbl<'_>, st: &mut State, label: String, at: &Range<usize>) {
        self.check_keys(t, &["stop", "decel", "decel_rad_s2", "label"], "a `stop` step");
        match self.string(t, "stop") {
            Ok(Some((s, _))) if s == "table" => {}
            Ok(Some((s, span))) => {
                self.err(&span, format!("`stop` takes \"table\", got \"{s}\""));
                return;
            }
            _ => return,
        }
        let decel_rad_s2 = match self.quantity(t, "decel", Dim::AngularAccel) {
            Ok(Some((a, span))) => {
                self.check_accel(&a, &span, "table deceleration");
                a.si
            }
            Ok(None) => self.table_accel,
            Err(Reported) => return,
        };
        self.push(st, "table_stop", label, at, Action::TableStop { decel_rad_s2 });
    }

    /// `wait`/`record` value: `"ramp end"` → `None`; a duration → `Some`.
    fn duration_or_ramp_end(&mut self, t: Tbl<'_>, key: &str, what: &str) -> Got<Option<Duration>> {
        if let Some(e) = t.get(key) {
            if let Value::Str(s) = &e.node.value {
                let s = self.subst(s, &e.node.span)?;
                if is_ramp_end(&s) {
                    return Ok(Some(None));
                }
            }
        }
        Ok(self.duration(t, key, what)?.map(|(d, _, _)| Some(d)))
    }

    /// The timeout of a ramp-end wait: given, or twice the ramp's nominal length plus 30 min.
    fn ramp_end_timeout(
        &mut self,
        t: Tbl<'_>,
        st: &State,
        at: &Range<usize>,
        what: &str,
    ) -> Option<Duration> {
        if !st.ramp_active {
            self.err(
                at,
                format!(
                    "{what} until \"ramp end\", but no chamber step starts a ramp before it (or \
                     its end was already waited for)"
                ),
            );
            return None;
        }
        match self.duration(t, "timeout", "timeout") {
            Ok(Some((d, _, _))) => Some(d),
            Ok(None) => Some(Duration::from_secs_f64(
                (2.0 * st.ramp_duration_s + 1800.0).min(MAX_DURATION_S),
            )),
            Err(Reported) => None,
        }
    }

    fn forbid_timeout(&mut self, t: Tbl<'_>) {
        for k in ["timeout", "timeout_s"] {
            if let Some(e) = t.get(k) {
                self.err(&e.key_span, format!("`{k}` only applies to \"ramp end\""));
            }
        }
    }

    fn wait_step(&mut self, t: Tbl<'_>, st: &mut State, label: String, at: &Range<usize>) {
        self.check_keys(t, &["wait", "wait_s", "timeout", "timeout_s", "label"], "a `wait` step");
        match self.duration_or_ramp_end(t, "wait", "wait") {
            Ok(Some(Some(duration))) => {
                self.forbid_timeout(t);
                self.push(st, "wait", label, at, Action::Wait { duration });
            }
            Ok(Some(None)) => {
                if let Some(timeout) = self.ramp_end_timeout(t, st, at, "wait") {
                    st.ramp_active = false;
                    self.push(st, "wait_ramp_end", label, at, Action::WaitRampEnd { timeout });
                }
            }
            _ => {}
        }
    }

    fn wait_temp_step(&mut self, t: Tbl<'_>, st: &mut State, label: String, at: &Range<usize>) {
        self.check_keys(
            t,
            &[
                "wait_temperature",
                "wait_temperature_c",
                "source",
                "band",
                "band_c",
                "hold",
                "hold_s",
                "timeout",
                "timeout_s",
                "label",
            ],
            "a `wait_temperature` step",
        );
        let target = self.quantity(t, "wait_temperature", Dim::Temperature);
        let source = match self.string(t, "source") {
            Ok(None) => Some(TempSource::Air),
            Ok(Some((s, span))) => match s.as_str() {
                "air" => Some(TempSource::Air),
                "gyro" => Some(TempSource::Gyro),
                other => {
                    self.err(&span, format!("source must be \"air\" or \"gyro\", got \"{other}\""));
                    None
                }
            },
            Err(Reported) => None,
        };
        let band = self.positive(t, "band", Dim::TempDifference, "band");
        let band = self.required(
            band,
            at,
            "`wait_temperature` needs `band` (half-width, e.g. \"0.5 °C\")",
        );
        let hold = self.duration(t, "hold", "hold");
        let hold = self.required(hold, at, "`wait_temperature` needs `hold` (e.g. \"10 min\")");
        let timeout = self.duration(t, "timeout", "timeout");
        let timeout =
            self.required(timeout, at, "`wait_temperature` needs `timeout` (e.g. \"2 h\")");
        let Ok(Some((target, tspan))) = target else {
            return;
        };
        let in_range = self.check_temp(&target, &tspan, "temperature");
        let (Some(source), Some((band, _)), Some((hold, _, holdq)), Some((timeout, tospan, toq))) =
            (source, band, hold, timeout)
        else {
            return;
        };
        if timeout < hold {
            self.err(
                &tospan,
                format!(
                    "timeout {} is shorter than hold {}; the wait could never succeed",
                    toq.show_self(),
                    holdq.show_self()
                ),
            );
            return;
        }
        if !in_range {
            return;
        }
        let lo = st.ramp_from_c.min(st.setpoint_c) - band.si;
        let hi = st.ramp_from_c.max(st.setpoint_c) + band.si;
        if !(lo..=hi).contains(&target.si) {
            self.err(
                &tspan,
                format!(
                    "waiting for {} ± {} can never succeed: the chamber is set to {} °C at this \
                     point",
                    target.show_self(),
                    band.show_self(),
                    fmt_num(st.setpoint_c)
                ),
            );
            return;
        }
        if (target.si - st.setpoint_c).abs() <= band.si {
            st.ramp_active = false;
        }
        self.push(
            st,
            "wait_temperature",
            label,
            at,
            Action::WaitTemperature { source, target_c: target.si, band_c: band.si, hold, timeout },
        );
    }

    fn record_step(
        &mut self,
        t: Tbl<'_>,
        st: &mut State,
        label: Option<(String, Range<usize>)>,
        at: &Range<usize>,
    ) {
        self.check_keys(
            t,
            &["record", "record_s", "timeout", "timeout_s", "label"],
            "a `record` step",
        );
        let label = match label {
            Some((l, span)) => {
                if !is_record_label(&l) {
                    self.err(
                        &span,
                        format!(
                            "the label of a record step must start with `record` (e.g. \"record \
                             cw 20C\"), got \"{l}\""
                        ),
                    );
                    return;
                }
                l
            }
            None => {
                if t.get("label").is_none() {
                    self.err(at, "a record step needs a label starting with `record`, e.g. \"record cw 20C\"");
                }
                return;
            }
        };
        match self.duration_or_ramp_end(t, "record", "record window") {
            Ok(Some(Some(duration))) => {
                self.forbid_timeout(t);
                self.push(
                    st,
                    "record",
                    label,
                    at,
                    Action::Record { duration, until_ramp_end: false },
                );
            }
            Ok(Some(None)) => {
                if let Some(duration) = self.ramp_end_timeout(t, st, at, "record") {
                    st.ramp_active = false;
                    self.push(
                        st,
                        "record",
                        label,
                        at,
                        Action::Record { duration, until_ramp_end: true },
                    );
                }
            }
            _ => {}
        }
    }

    fn for_step(&mut self, t: Tbl<'_>, st: &mut State, for_entry: &Entry) {
        self.check_keys(t, &["for", "do", "label"], "a `for` step");
        let Value::Table(var_entries) = &for_entry.node.value else {
            self.err(
                &for_entry.node.span,
                "`for` must be a table of loop variables, e.g. `for.temp = [-40, 20, 60]`",
            );
            return;
        };
        if var_entries.is_empty() {
            self.err(&for_entry.node.span, "`for` declares no loop variable");
            return;
        }
        let mut lists: Vec<(String, Vec<String>)> = Vec::new();
        let mut ok = true;
        for e in var_entries {
            let valid_name =
                e.key.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
                    && e.key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
            if !valid_name {
                self.err(
                    &e.key_span,
                    format!("loop variable `{}` must be a name of letters, digits and _", e.key),
                );
                ok = false;
                continue;
            }
            if self.vars.iter().any(|(k, _)| *k == e.key) {
                self.err(
                    &e.key_span,
                    format!("loop variable `{}` is already defined by an enclosing loop", e.key),
                );
                ok = false;
                continue;
            }
            let Value::Array(items) = &e.node.value else {
                self.err(
                    &e.node.span,
                    format!("loop variable `{}` must be a list, e.g. [-40, 20, 60] or [\"cw\", \"ccw\"]", e.key),
                );
                ok = false;
                continue;
            };
            if items.is_empty() {
                self.err(&e.node.span, format!("loop variable `{}` has an empty list", e.key));
                ok = false;
                continue;
            }
            let mut values = Vec::new();
            for it in items {
                match &it.value {
                    Value::Num(x) if x.is_finite() => values.push(format!("{x}")),
                    Value::Str(s) => match self.subst(s, &it.span) {
                        Ok(s) => values.push(s),
                        Err(Reported) => ok = false,
                    },
                    v => {
                        self.err(
                            &it.span,
                            format!(
                                "loop values must be numbers or strings, got {}",
                                v.type_name()
                            ),
                        );
                        ok = false;
                    }
                }
            }
            lists.push((e.key.clone(), values));
        }
        let Some(body) = t.get("do") else {
            self.err(t.span, "a `for` step needs steps to repeat: add [[step.do]] tables");
            return;
        };
        if matches!(&body.node.value, Value::Array(a) if a.is_empty()) {
            self.err(&body.key_span, "`do` has no steps");
            return;
        }
        if !ok {
            return;
        }
        self.expand(&lists, &body.node, st);
    }

    /// Run the body for every combination of the loop lists, first list outermost.
    fn expand(&mut self, lists: &[(String, Vec<String>)], body: &Node, st: &mut State) {
        let Some(((name, values), rest)) = lists.split_first() else {
            self.steps_array(body, "do", st);
            return;
        };
        for v in values {
            if st.overflow {
                return;
            }
            self.vars.push((name.clone(), v.clone()));
            self.expand(rest, body, st);
            self.vars.pop();
        }
    }
}

/// Suffix of an action key's plain-SI form (`wait_s`), if it has one.
fn action_si_suffix(action: &str) -> Option<&'static str> {
    match action {
        "chamber" | "wait_temperature" => Some(Dim::Temperature.si_suffix()),
        "spin" => Some(Dim::AngularRate.si_suffix()),
        "wait" | "record" => Some(Dim::Time.si_suffix()),
        _ => None,
    }
}

fn is_ramp_end(s: &str) -> bool {
    let norm: Vec<&str> =
        s.split(|c: char| c.is_whitespace() || c == '_').filter(|w| !w.is_empty()).collect();
    norm == ["ramp", "end"]
}

/// Replace `{name}` by the loop variable's value; `{{` and `}}` are literal braces.
pub(crate) fn substitute(s: &str, vars: &[(String, String)]) -> Result<String, String> {
    if !s.contains(['{', '}']) {
        return Ok(s.to_string());
    }
    let mut out = String::with_capacity(s.len());
    let mut chars = s.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '{' if chars.peek() == Some(&'{') => {
                chars.next();
                out.push('{');
            }
            '}' if chars.peek() == Some(&'}') => {
                chars.next();
                out.push('}');
            }
            '{' => {
                let mut name = String::new();
                let mut closed = false;
                for n in chars.by_ref() {
                    if n == '}' {
                        closed = true;
                        break;
                    }
                    name.push(n);
                }
                if !closed {
                    return Err(format!(
                        "unclosed `{{` in \"{s}\" (write `{{{{` for a literal brace)"
                    ));
                }
                // Innermost loop wins (shadowing is rejected anyway).
                match vars.iter().rev().find(|(k, _)| *k == name) {
                    Some((_, v)) => out.push_str(v),
                    None if vars.is_empty() => {
                        return Err(format!(
                            "`{{{name}}}` is not a loop variable: no `for` step encloses this one"
                        ));
                    }
                    None => {
                        let known = vars
                            .iter()
                            .map(|(k, _)| format!("{{{k}}}"))
                            .collect::<Vec<_>>()
                            .join(", ");
                        return Err(format!(
                            "unknown loop variable `{{{name}}}`; defined here: {known}"
                        ));
                    }
                }
            }
            '}' => {
                return Err(format!("unmatched `}}` in \"{s}\" (write `}}}}` for a literal brace)"))
            }
            c => out.push(c),
        }
    }
    Ok(out)
}

/// A step's keys that are not actions, never taken for a misspelt one.
const NOT_ACTIONS: &[&str] =
    &["label", "do", "direction", "ramp", "timeout", "band", "hold", "source", "accel", "decel"];

/// The allowed key closest to `key` (edit distance ≤ 2), for "did you mean".
fn closest<'k>(key: &str, allowed: &[&'k str]) -> Option<&'k str> {
    allowed
        .iter()
        .map(|a| (edit_distance(key, a), *a))
        .filter(|(d, _)| *d <= 2)
        .min_by_key(|(d, _)| *d)
        .map(|(_, a)| a)
}

fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1];
        for (j, cb) in b.iter().enumerate() {
            let sub = prev.get(j).copied().unwrap_or(0) + usize::from(ca != *cb);
            let del = prev.get(j + 1).copied().unwrap_or(0) + 1;
            let ins = cur.get(j).copied().unwrap_or(0) + 1;
            cur.push(sub.min(del).min(ins));
        }
        prev = cur;
    }
    prev.last().copied().unwrap_or(0)
}
