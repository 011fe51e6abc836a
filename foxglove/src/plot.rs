//! The plot channel: the robot's 1 kHz quantities decimated to [`RATE`] ticks a second of plant
//! time, for Foxglove's plot panels.
//!
//! A plot panel keeps and redraws every message in its window: fed the 1 kHz state (10,000
//! points in a 10 s window, per series), Foxglove Studio 1.48 fell behind and its plots went
//! blank for 3-5 s at a time. `/tilting/NAME/plot` carries one message per tick of
//! [`TICK_NS`] (50 a second of plant time) with, for each quantity, the least and the greatest
//! of the tick's samples ([`Decimator`]).
//!
//! Why the min and the max, not the sample nearest the tick: a tick spans 20 samples, and what
//! a user looks for in these plots is short: the torque's spikes at impacts (up to about
//! 30 N m, a few ms long) and the tilt's peaks. A sample every 20 ms would miss most spikes and
//! draw the ones it hits at random heights; the min and the max of each tick bound every 1 kHz
//! sample (the band between the two lines holds the full-rate curve), and each peak is drawn at
//! its exact value, late by at most one tick. The full-rate channels stay for the 3D panel,
//! recordings and users who want every sample.
//!
//! Each message also carries `header.stamp`, its tick on the viewer's clock ([`WallStamp`]), which
//! the layout's plots use as their x (`timestampMethod: headerStamp`): Studio 1.48 stamps a
//! live message with the time the browser reads it (`receiveTime`), and a browser short of CPU
//! reads them in bursts, so plotted by receive time a second of ticks collapsed onto one
//! instant and the plot drew straight lines between bursts (seen in a screenshot under load).

use serde_json::{json, Map, Value};
use std::collections::BTreeMap;

/// The tick, ns of plant time: 50 plot messages per second of plant time.
pub const TICK_NS: u64 = 20_000_000;

/// Plot messages per second of plant time.
pub const RATE: f64 = 1e9 / TICK_NS as f64;

/// The plot channel's schema name.
pub const PLOT_SCHEMA: &str = "tilting.Plot";

/// A decimated quantity.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Field {
    /// The tilt `alpha` (rad).
    Alpha,
    /// The arm angle `beta` relative to the plate (rad).
    Beta,
    /// The commanded joint torque `tau` (N m).
    Tau,
    /// The model's total energy `E` (J).
    Energy,
    /// The adapted stiffness `K_P` (1/s²).
    Gain,
}

/// Each field's JSON name and its description (unit included), in [`Field`] order.
pub const FIELDS: [(Field, &str, &str); 5] = [
    (Field::Alpha, "alpha", "tilt alpha, rad"),
    (
        Field::Beta,
        "beta",
        "arm angle beta relative to the plate, rad",
    ),
    (
        Field::Tau,
        "tau",
        "commanded joint torque tau on beta, N m (the torques received in the tick, stamped \
         with the latest plant time when they arrived)",
    ),
    (
        Field::Energy,
        "energy",
        "total energy E = T + V of the model, J (states carrying their rates)",
    ),
    (
        Field::Gain,
        "gain",
        "adapted stiffness K_P = kp + k (energy_avg - E) of the latest planner/reference (kp \
         when k = 0 or the reference is an excitation), 1/s^2; absent before a reference",
    ),
];

/// The plot channel's JSON Schema: `time` (s, the tick's centre), and for each [`FIELDS`]
/// entry `NAME_min` and `NAME_max`, present when the tick had a sample of it.
pub fn schema() -> Value {
    let mut props = Map::new();
    props.insert(
        "time".into(),
        json!({"type": "number", "description":
            "Plant time of the tick's centre, s; the tick spans time - 0.01 to time + 0.01."}),
    );
    for (_, name, what) in FIELDS {
        for (end, word) in [("min", "least"), ("max", "greatest")] {
            props.insert(
                format!("{name}_{end}"),
                json!({"type": "number", "description":
                    format!("The {word} {what} in the tick.")}),
            );
        }
    }
    let int = |what: &str| json!({"type": "integer", "description": what});
    props.insert(
        "header".into(),
        json!({"type": "object", "description":
            "The tick's centre on the viewer's clock (the wall clock when the server saw the \
             first tick, plus the plant time since): what plot panels read as the message's \
             time (Foxglove's `header.stamp`).",
            "properties": {"stamp": {"type": "object", "properties": {
                "sec": int("s since the Unix epoch"),
                "nsec": int("ns within the second, 0 to 999,999,999")},
                "required": ["sec", "nsec"], "additionalProperties": false}},
            "required": ["stamp"], "additionalProperties": false}),
    );
    json!({
        "title": PLOT_SCHEMA,
        "type": "object",
        "properties": props,
        "required": ["time"],
        "additionalProperties": false,
    })
}

/// Per field, `(min, max)` of a tick's samples.
type Ranges = [Option<(f64, f64)>; 5];

/// Decimates samples stamped in plant time (ns) into ticks of [`TICK_NS`]: per tick, each
/// field's least and greatest value. A tick is sent once a sample two ticks later arrives: a
/// recording logs a torque at the time of the state it answers, which may come after the next
/// state, and one tick of grace keeps it in its own tick. A sample later still (its tick sent)
/// counts in the first tick not sent.
#[derive(Debug, Clone, Default)]
pub struct Decimator {
    /// The open ticks by index (`time / TICK_NS`).
    open: BTreeMap<u64, Ranges>,
    /// The first tick not sent yet.
    next: u64,
}

impl Decimator {
    /// Adds the samples `values` taken at plant time `t_ns`; returns the messages of the ticks
    /// this closes, in time order, each with its log time (ns, the tick's centre). Non-finite
    /// values are ignored.
    pub fn add(&mut self, t_ns: u64, values: &[(Field, f64)]) -> Vec<(u64, Value)> {
        let tick = (t_ns / TICK_NS).max(self.next);
        let range = self.open.entry(tick).or_default();
        for &(field, v) in values.iter().filter(|(_, v)| v.is_finite()) {
            let r = &mut range[field as usize];
            *r = Some(r.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v))));
        }
        let mut done = Vec::new();
        while let Some(first) = self.open.first_entry() {
            if *first.key() + 1 >= tick {
                break;
            }
            let (k, r) = first.remove_entry();
            self.next = k + 1;
            done.extend(message(k, r));
        }
        done
    }

    /// Closes every open tick: their messages and log times (ns), in time order.
    pub fn flush(&mut self) -> Vec<(u64, Value)> {
        let open = std::mem::take(&mut self.open);
        if let Some(&last) = open.keys().next_back() {
            self.next = last + 1;
        }
        open.into_iter()
            .filter_map(|(k, r)| message(k, r))
            .collect()
    }
}

/// Plant time mapped onto the wall clock (ns since the Unix epoch) by one fixed offset, taken
/// at the first tick: the wall clock then minus the tick's plant time. Stamps are then exactly
/// the plant time's spacing (20 ms a tick), however late or bunched the ticks are published or
/// read; at real time they track the wall clock, as a live viewer's own clock does.
#[derive(Debug, Clone, Copy, Default)]
pub struct WallStamp {
    /// Wall clock minus plant time (ns), once known.
    offset: Option<i128>,
}

impl WallStamp {
    /// The wall-clock time (ns since the Unix epoch, 0 at the earliest) of plant time `t_ns`
    /// (ns); `now_ns` (the wall clock, ns since the Unix epoch) fixes the offset at the first
    /// call and is ignored after.
    pub fn at(&mut self, t_ns: u64, now_ns: u128) -> u128 {
        let offset = *self.offset.get_or_insert(now_ns as i128 - i128::from(t_ns));
        (i128::from(t_ns) + offset).max(0) as u128
    }
}

/// Adds `header.stamp` (`sec`, `nsec`) for `wall_ns` (ns since the Unix epoch) to a plot
/// message (a JSON object; anything else is left as it is).
pub fn stamp(message: &mut Value, wall_ns: u128) {
    if let Value::Object(m) = message {
        let (sec, nsec) = (wall_ns / 1_000_000_000, wall_ns % 1_000_000_000);
        m.insert(
            "header".into(),
            json!({"stamp": {"sec": sec as u64, "nsec": nsec as u64}}),
        );
    }
}

/// Tick `tick`'s message and log time (ns, its centre), if it had any sample.
fn message(tick: u64, range: Ranges) -> Option<(u64, Value)> {
    if range.iter().all(Option::is_none) {
        return None;
    }
    let centre = tick * TICK_NS + TICK_NS / 2;
    let mut m = Map::new();
    m.insert("time".into(), json!(centre as f64 * 1e-9));
    for ((_, name, _), r) in FIELDS.iter().zip(range) {
        if let Some((lo, hi)) = r {
            m.insert(format!("{name}_min"), json!(lo));
            m.insert(format!("{name}_max"), json!(hi));
        }
    }
    Some((centre, Value::Object(m)))
}

/// The adapted stiffness `K_P = kp + k (energy_avg - E)` (1/s²) of reference `r` at energy `e`
/// (J), as the controller adapts it: `kp` when `k` is 0 or the reference is an excitation.
pub fn gain(r: &tilting_proto::Reference, e: f64) -> f64 {
    if r.k == 0.0 || r.kind == tilting_proto::Reference::EXCITATION {
        r.kp
    } else {
        r.kp + r.k * (r.energy_avg - e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sine sampled at 1 kHz for 1 s: 50 ticks, each bounding its 20 samples exactly, the
    /// peak kept at its value, the times the ticks' centres 20 ms apart.
    #[test]
    fn ticks_bound_every_sample_and_keep_the_peaks() {
        let f = |i: u64| (2.0 * std::f64::consts::PI * 3.0 * i as f64 * 1e-3).sin();
        let mut d = Decimator::default();
        let mut out: Vec<(u64, Value)> = (0..1000u64)
            .flat_map(|i| d.add(i * 1_000_000, &[(Field::Alpha, f(i))]))
            .collect();
        out.extend(d.flush());
        assert_eq!(out.len(), 50);
        for (k, (t, m)) in out.iter().enumerate() {
            let k = k as u64;
            assert_eq!(*t, k * 20_000_000 + 10_000_000);
            assert_eq!(m["time"].as_f64().unwrap(), *t as f64 * 1e-9);
            let samples: Vec<f64> = (20 * k..20 * k + 20).map(f).collect();
            let lo = samples.iter().cloned().fold(f64::INFINITY, f64::min);
            let hi = samples.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            assert_eq!(m["alpha_min"].as_f64(), Some(lo));
            assert_eq!(m["alpha_max"].as_f64(), Some(hi));
            // Only the fields sampled.
            assert!(m.get("tau_min").is_none() && m.get("beta_max").is_none());
        }
        // The greatest of the maxima is the sine's greatest sample: no peak lost.
        let peak = out
            .iter()
            .map(|(_, m)| m["alpha_max"].as_f64().unwrap())
            .fold(f64::NEG_INFINITY, f64::max);
        let want = (0..1000).map(f).fold(f64::NEG_INFINITY, f64::max);
        assert_eq!(peak, want);
    }

    /// A one-sample spike shows in its tick, a sample one tick late still counts in its own
    /// tick, a tick without samples sends nothing; a sample later still counts in the first
    /// tick not sent, NaN nowhere.
    #[test]
    fn a_spike_is_kept_and_empty_ticks_are_skipped() {
        let mut d = Decimator::default();
        assert!(d.add(0, &[(Field::Tau, 1.0)]).is_empty());
        let nan = [(Field::Tau, -30.0), (Field::Gain, f64::NAN)];
        assert!(d.add(7_000_000, &nan).is_empty());
        assert!(d.add(21_000_000, &[(Field::Tau, 4.0)]).is_empty());
        // Late by one tick: still tick 0's.
        assert!(d.add(19_000_000, &[(Field::Tau, 2.0)]).is_empty());
        // Three ticks on: ticks 0 and 1 close; 2 (empty) sends nothing.
        let done = d.add(60_000_000, &[(Field::Tau, 0.5)]);
        assert_eq!(done.len(), 2);
        let (t, m) = &done[0];
        assert_eq!(*t, 10_000_000);
        assert_eq!(
            (m["tau_min"].as_f64(), m["tau_max"].as_f64()),
            (Some(-30.0), Some(2.0))
        );
        assert!(m.get("gain_min").is_none());
        assert_eq!(done[1].0, 30_000_000);
        assert_eq!(done[1].1["tau_max"].as_f64(), Some(4.0));
        // Tick 1 is sent: a sample of it now counts in tick 2, the first not sent.
        assert!(d.add(25_000_000, &[(Field::Tau, 9.0)]).is_empty());
        let done = d.flush();
        assert_eq!(done.len(), 2);
        assert_eq!(done[0].0, 50_000_000);
        assert_eq!(done[0].1["tau_max"].as_f64(), Some(9.0));
        assert_eq!(done[1].0, 70_000_000);
        assert_eq!(done[1].1["tau_max"].as_f64(), Some(0.5));
        assert!(d.flush().is_empty());
    }

    /// The schema names every field the messages carry, each a number but the header (two
    /// integers), and nothing else.
    #[test]
    fn the_schema_lists_what_the_messages_carry() {
        let s = schema();
        let props = s["properties"].as_object().unwrap();
        assert_eq!(props.len(), 2 + 2 * FIELDS.len());
        let mut d = Decimator::default();
        let all: Vec<_> = FIELDS.iter().map(|&(f, _, _)| (f, 1.0)).collect();
        d.add(0, &all);
        let (_, mut m) = d.flush().pop().unwrap();
        stamp(&mut m, 1_700_000_000_123_456_789);
        for (k, v) in m.as_object().unwrap() {
            if k == "header" {
                let st = &props[k]["properties"]["stamp"]["properties"];
                for f in ["sec", "nsec"] {
                    assert_eq!(st[f]["type"], "integer");
                    assert!(v["stamp"][f].is_u64(), "{v}");
                }
                assert_eq!(v["stamp"].as_object().unwrap().len(), 2);
            } else {
                assert_eq!(props[k]["type"], "number", "{k}");
            }
        }
        assert_eq!(m.as_object().unwrap().len(), props.len());
    }

    /// Stamps keep the plant time's spacing whatever the wall clock at publication: ticks
    /// published in one burst (the same `now`) or late are 20 ms apart on the viewer's clock,
    /// the first at the wall clock when it was stamped; sec and nsec split the ns exactly.
    #[test]
    fn stamps_follow_plant_time_not_publication() {
        let mut w = WallStamp::default();
        let start = 1_800_000_000_000_000_000u128;
        let first = 10_000_000u64;
        assert_eq!(w.at(first, start), start);
        // Ten ticks published together a second later, then one published early.
        let later = start + 1_000_000_000;
        for k in 1..=10u64 {
            let t = first + k * TICK_NS;
            assert_eq!(w.at(t, later), start + u128::from(k * TICK_NS));
        }
        assert_eq!(w.at(first + 11 * TICK_NS, start), start + 220_000_000);
        let mut m = json!({"time": 0.01});
        stamp(&mut m, start + 220_000_000);
        assert_eq!(m["header"]["stamp"]["sec"], 1_800_000_000u64);
        assert_eq!(m["header"]["stamp"]["nsec"], 220_000_000u64);
    }

    /// The gain: `kp + k (E_av - E)`, or `kp` without adaptation.
    #[test]
    fn the_gain_is_the_controllers_stiffness() {
        let mut r = tilting_proto::Reference {
            kind: tilting_proto::Reference::SINUSOID,
            amplitude: 0.1,
            omega: 10.0,
            kp: 100.0,
            kd: 20.0,
            k: 2.0,
            energy_avg: 20.0,
            torque_limit: 0.0,
        };
        assert_eq!(gain(&r, 18.5), 103.0);
        r.kind = tilting_proto::Reference::EXCITATION;
        assert_eq!(gain(&r, 18.5), 100.0);
        r.kind = tilting_proto::Reference::HOLD;
        r.k = 0.0;
        assert_eq!(gain(&r, 18.5), 100.0);
    }
}
