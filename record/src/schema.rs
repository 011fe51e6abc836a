//! JSON Schemas of the five messages, and the JSON form of a wire payload.
//!
//! The JSON objects are the messages' serde form (field names as in `tilting_proto::msg`);
//! the schemas are written here by hand, with units, and a test checks they list exactly the
//! fields the JSON carries.

use serde_json::{json, Map, Value};
use tilting_proto::{codec, DecodeError, ModeEvent, PlantState, Reference, Status, Topic};
use tilting_proto::{Message, TorqueCommand};

/// Kind of a JSON field.
#[derive(Clone, Copy)]
enum Kind {
    /// Unsigned integer.
    Int,
    /// Finite number.
    Num,
    /// Four numbers `[alpha, beta, alpha_dot, beta_dot]`.
    State4,
    /// UTF-8 text.
    Text,
}

use Kind::*;

/// The fields of each message: name, kind, description with units.
fn fields(topic: Topic) -> &'static [(&'static str, Kind, &'static str)] {
    match topic {
        Topic::State => &[
            ("seq", Int, "sample number, strictly increasing from 0"),
            ("time", Num, "plant time, s"),
            (
                "alpha",
                Num,
                "plate tilt angle, rad, counter-clockwise positive",
            ),
            (
                "beta",
                Num,
                "arm angle relative to the plate, rad, pi/2 upright",
            ),
            ("alpha_dot", Num, "plate tilt rate, rad/s"),
            ("beta_dot", Num, "arm rate relative to the plate, rad/s"),
            ("mode", Int, "contact mode: 0 flat, 1 left, 2 right"),
        ],
        Topic::Torque => &[
            ("seq", Int, "seq of the state this torque answers"),
            ("tau", Num, "arm motor torque, N m"),
        ],
        Topic::Event => &[
            (
                "seq",
                Int,
                "seq of the last state published before the event",
            ),
            ("time", Num, "plant time of the event, s"),
            ("from", Int, "mode before: 0 flat, 1 left, 2 right"),
            ("to", Int, "mode after: 0 flat, 1 left, 2 right"),
            (
                "x_before",
                State4,
                "[alpha, beta, alpha_dot, beta_dot] just before, rad and rad/s",
            ),
            (
                "x_after",
                State4,
                "[alpha, beta, alpha_dot, beta_dot] just after, rad and rad/s",
            ),
        ],
        Topic::Status => &[
            ("seq", Int, "seq of the last published state"),
            ("time", Num, "plant time, s"),
            (
                "state",
                Int,
                "0 starting, 1 running, 2 safe mode, 3 faulted, 4 stopped",
            ),
            ("mode", Int, "contact mode: 0 flat, 1 left, 2 right"),
            ("tilts", Int, "tilts (flat to left or right) since start"),
            ("steps", Int, "control periods since start"),
            (
                "torques_received",
                Int,
                "torque commands received, valid or not",
            ),
            (
                "torques_dropped",
                Int,
                "torque commands that did not decode or validate",
            ),
            (
                "torques_stale",
                Int,
                "valid torque commands not applied (too old)",
            ),
            ("deadline_misses", Int, "periods whose torque came too late"),
            ("watchdog_trips", Int, "entries into safe mode"),
            ("jitter_p50_us", Num, "median period jitter, us"),
            ("jitter_p99_us", Num, "99th percentile of period jitter, us"),
            ("max_overrun_us", Num, "largest period overrun, us"),
            ("latency_p50_us", Num, "median loop latency, us"),
            ("latency_p99_us", Num, "99th percentile of loop latency, us"),
            (
                "torques_late",
                Int,
                "torques applied after their own period",
            ),
            ("torques_lost", Int, "states whose answer was never applied"),
            (
                "torques_reordered",
                Int,
                "torques that arrived after a newer one",
            ),
            ("age_p50", Num, "median age of the applied torques, periods"),
            ("age_p99", Num, "99th percentile of the age, periods"),
            ("age_max", Num, "largest age, periods"),
            ("fault", Text, "fault description, empty if none"),
        ],
        Topic::Reference => &[
            ("kind", Int, "0 hold beta_d = pi/2, 1 sinusoid"),
            ("amplitude", Num, "sinusoid amplitude A, rad"),
            ("omega", Num, "sinusoid angular frequency w, rad/s"),
            ("kp", Num, "nominal proportional gain K_P0, 1/s^2"),
            ("kd", Num, "derivative gain K_D, 1/s"),
            ("k", Num, "energy adaptation gain k, 1/(J s^2)"),
            ("energy_avg", Num, "target average energy E_av, J"),
            ("torque_limit", Num, "torque saturation, N m (0 = none)"),
        ],
    }
}

/// The schema's name: `tilting.<MessageType>`.
pub fn schema_name(topic: Topic) -> String {
    format!("tilting.{}", topic.message_type())
}

/// The JSON Schema (draft 2020-12) of `topic`'s JSON messages.
pub fn json_schema(topic: Topic) -> Value {
    let mut props = Map::new();
    for &(name, kind, description) in fields(topic) {
        let p = match kind {
            Int => json!({ "type": "integer", "minimum": 0, "description": description }),
            Num => json!({ "type": "number", "description": description }),
            Text => json!({ "type": "string", "description": description }),
            State4 => json!({
                "type": "array",
                "items": { "type": "number" },
                "minItems": 4,
                "maxItems": 4,
                "description": description
            }),
        };
        props.insert(name.to_owned(), p);
    }
    let required: Vec<&str> = fields(topic).iter().map(|f| f.0).collect();
    json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": schema_name(topic),
        "type": "object",
        "properties": props,
        "required": required,
        "additionalProperties": false
    })
}

/// Decodes and validates a wire payload of `topic` and returns its JSON object (UTF-8).
pub fn to_json(topic: Topic, wire: &[u8]) -> Result<Vec<u8>, DecodeError> {
    fn enc<T: Message + serde::Serialize>(wire: &[u8]) -> Result<Vec<u8>, DecodeError> {
        let m: T = codec::decode(wire)?;
        // Serialising a struct of numbers and a string cannot fail.
        Ok(serde_json::to_vec(&m).unwrap_or_default())
    }
    match topic {
        Topic::State => enc::<PlantState>(wire),
        Topic::Torque => enc::<TorqueCommand>(wire),
        Topic::Event => enc::<ModeEvent>(wire),
        Topic::Status => enc::<Status>(wire),
        Topic::Reference => enc::<Reference>(wire),
    }
}

/// A JSON object that is not a valid message of its topic.
#[derive(Debug, thiserror::Error)]
pub enum FromJsonError {
    /// Not JSON of the message's shape.
    #[error("{0}")]
    Json(#[from] serde_json::Error),
    /// The message does not validate (e.g. a mode byte out of range).
    #[error("{0}")]
    Invalid(#[from] tilting_proto::ValidationError),
}

/// The wire payload of a JSON object of `topic`: the inverse of [`to_json`], byte for byte
/// (JSON numbers are written in shortest round-trip form and parsed correctly rounded, and the
/// wire encoding of a message is unique), after the message's own validation.
pub fn from_json(topic: Topic, json: &[u8]) -> Result<Vec<u8>, FromJsonError> {
    fn dec<T: Message + serde::de::DeserializeOwned>(
        json: &[u8],
    ) -> Result<Vec<u8>, FromJsonError> {
        let m: T = serde_json::from_slice(json)?;
        m.validate()?;
        Ok(codec::encode(&m))
    }
    match topic {
        Topic::State => dec::<PlantState>(json),
        Topic::Torque => dec::<TorqueCommand>(json),
        Topic::Event => dec::<ModeEvent>(json),
        Topic::Status => dec::<Status>(json),
        Topic::Reference => dec::<Reference>(json),
    }
}

/// The topic whose schema is named `name` (`tilting.PlantState`, ...).
pub fn topic_of_schema(name: &str) -> Option<Topic> {
    let ty = name.strip_prefix("tilting.")?;
    Topic::ALL.into_iter().find(|t| t.message_type() == ty)
}

#[cfg(test)]
mod tests {
    use super::*;
    use tilting_proto::encode;

    fn samples() -> Vec<(Topic, Vec<u8>)> {
        vec![
            (
                Topic::State,
                encode(&PlantState {
                    seq: 3,
                    time: 0.003,
                    alpha: 0.01,
                    beta: 1.5,
                    alpha_dot: -0.2,
                    beta_dot: 0.3,
                    mode: 1,
                }),
            ),
            (Topic::Torque, encode(&TorqueCommand { seq: 3, tau: -1.25 })),
            (
                Topic::Event,
                encode(&ModeEvent {
                    seq: 3,
                    time: 0.0031,
                    from: 0,
                    to: 2,
                    x_before: [0.0, 1.5, 0.0, 0.1],
                    x_after: [0.0, 1.5, 0.0, 0.1],
                }),
            ),
            (
                Topic::Status,
                encode(&Status {
                    seq: 3,
                    time: 0.003,
                    state: Status::RUNNING,
                    mode: 1,
                    tilts: 2,
                    steps: 4,
                    torques_received: 4,
                    jitter_p50_us: 1.0,
                    jitter_p99_us: 2.0,
                    max_overrun_us: 3.0,
                    latency_p50_us: 4.0,
                    latency_p99_us: 5.0,
                    fault: "none".into(),
                    ..Status::default()
                }),
            ),
            (
                Topic::Reference,
                encode(&Reference {
                    kind: 1,
                    amplitude: 0.5,
                    omega: 7.0,
                    kp: 100.0,
                    kd: 20.0,
                    k: 500.0,
                    energy_avg: 1.0,
                    torque_limit: 0.0,
                }),
            ),
        ]
    }

    /// The schema lists exactly the JSON's fields, with matching JSON types, and every field
    /// is required: a message or schema edited alone fails here.
    #[test]
    fn schemas_match_the_json() {
        for (topic, wire) in samples() {
            let v: Value = serde_json::from_slice(&to_json(topic, &wire).unwrap()).unwrap();
            let obj = v.as_object().unwrap();
            let schema = json_schema(topic);
            let props = schema["properties"].as_object().unwrap();
            let mut a: Vec<_> = obj.keys().collect();
            let mut b: Vec<_> = props.keys().collect();
            a.sort();
            b.sort();
            assert_eq!(a, b, "{topic}");
            for (k, val) in obj {
                let ty = props[k]["type"].as_str().unwrap();
                let ok = match ty {
                    "integer" => val.is_u64(),
                    "number" => val.is_number(),
                    "string" => val.is_string(),
                    "array" => val.as_array().is_some_and(|a| a.len() == 4),
                    _ => false,
                };
                assert!(ok, "{topic}.{k}: {val} is not a {ty}");
            }
            assert_eq!(schema["required"].as_array().unwrap().len(), props.len());
        }
    }

    #[test]
    fn json_round_trips_the_floats_exactly() {
        let s = PlantState {
            seq: 1,
            time: 0.1 + 0.2,
            alpha: 1e-300,
            beta: std::f64::consts::FRAC_PI_2,
            alpha_dot: -0.0,
            beta_dot: 1.0 / 3.0,
            mode: 0,
        };
        let back: PlantState =
            serde_json::from_slice(&to_json(Topic::State, &encode(&s)).unwrap()).unwrap();
        assert_eq!(back, s);
    }

    /// Every sample payload survives JSON and back byte for byte, including the awkward
    /// floats (-0.0, subnormals, 1/3) and the status text.
    #[test]
    fn wire_bytes_are_recovered_exactly_from_json() {
        for (topic, wire) in samples() {
            let back = from_json(topic, &to_json(topic, &wire).unwrap()).unwrap();
            assert_eq!(back, wire, "{topic}");
            assert_eq!(topic_of_schema(&schema_name(topic)), Some(topic));
        }
        let s = PlantState {
            seq: u64::MAX,
            time: 5e-324,
            alpha: -0.0,
            beta: 1.0 / 3.0,
            alpha_dot: f64::MAX,
            beta_dot: -f64::MIN_POSITIVE,
            mode: 2,
        };
        let wire = encode(&s);
        assert_eq!(
            from_json(Topic::State, &to_json(Topic::State, &wire).unwrap()).unwrap(),
            wire
        );
        // A JSON object out of range is refused with the field named.
        let e = from_json(
            Topic::State,
            br#"{"seq":0,"time":0,"alpha":0,"beta":0,"alpha_dot":0,"beta_dot":0,"mode":7}"#,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("mode"), "{e}");
    }

    #[test]
    fn a_payload_that_does_not_decode_is_refused() {
        assert!(to_json(Topic::State, &[1, 2, 3]).is_err());
    }
}
