//! JSON Schemas of the five messages, and the JSON form of a wire payload.
//!
//! The JSON objects are the messages' serde form (field names as in `tilting_proto::msg`);
//! the schemas are derived from the same structs (`schemars`, through `tilting-proto`'s
//! `schema` feature: field names, JSON types, and the fields' documentation with units as
//! descriptions), for the JSON the writer emits: every field required, no other field. A test
//! checks each schema against the JSON of a message.
//!
//! The reference topic carries either layout of the planner's message (protocol 3,
//! `tilting_proto::AnyReference`): the paper law's 57-byte `Reference` or any law's 107-byte
//! `LawReference`. Its one JSON form ([`ReferenceJson`]) has `kind`, `amplitude` and `omega`
//! always, then either the paper's five named gains (`kp` ... `torque_limit`) or the law's
//! name and parameters (`law`, `parameters`): which fields are present tells the layouts apart,
//! so [`from_json`] gives back the bytes as sent, 57 or 107.
//!
//! Next to each enumeration byte the JSON carries its name ([`NAMES`]: `mode` 1 and
//! `mode_name` `"left"`, a status' `state_name` `"safe mode"`, ...), so a viewer (Foxglove's
//! raw messages, a plot's tooltip) shows a word; the numbers stay for plots and programs.

use schemars::generate::SchemaSettings;
use schemars::JsonSchema;
use serde_json::Value;
use tilting_proto::{codec, DecodeError, ModeEvent, PlantState, Reference, Status, Topic};
use tilting_proto::{AnyReference, LawReference};
use tilting_proto::{Message, TorqueCommand};

/// The schema's name: `tilting.<MessageType>`.
pub fn schema_name(topic: Topic) -> String {
    format!("tilting.{}", topic.message_type())
}

/// The JSON Schema (draft 2020-12) of `topic`'s JSON messages, titled [`schema_name`].
pub fn json_schema(topic: Topic) -> Value {
    fn of<T: JsonSchema>() -> Value {
        SchemaSettings::draft2020_12()
            .for_serialize()
            .into_generator()
            .into_root_schema_for::<T>()
            .to_value()
    }
    let mut v = match topic {
        Topic::State => of::<PlantState>(),
        Topic::Torque => of::<TorqueCommand>(),
        Topic::Event => of::<ModeEvent>(),
        Topic::Status => of::<Status>(),
        Topic::Reference => of::<ReferenceJson>(),
    };
    v["title"] = schema_name(topic).into();
    one_type_per_field(&mut v);
    for &(t, field, name, values) in NAMES {
        if t != topic {
            continue;
        }
        let described = v["properties"][field]["description"].clone();
        let what = described.as_str().unwrap_or(field);
        v["properties"][name] = serde_json::json!({
            "type": "string",
            "enum": values,
            "description": format!("The name of `{field}` ({}): {what}", values.join(", ")),
        });
        if let Some(req) = v["required"].as_array_mut() {
            req.push(name.into());
        }
    }
    v
}

/// The enumeration bytes of the JSON messages and the names written next to them: topic, the
/// byte's field, the name's field, and the names of the values 0, 1, ... in order.
pub const NAMES: &[(Topic, &str, &str, &[&str])] = &[
    (Topic::State, "mode", "mode_name", MODES),
    (Topic::Event, "from", "from_name", MODES),
    (Topic::Event, "to", "to_name", MODES),
    (Topic::Status, "state", "state_name", STATES),
    (Topic::Status, "mode", "mode_name", MODES),
    (Topic::Reference, "kind", "kind_name", KINDS),
];

/// The contact modes by byte (`tilting_proto::Mode`).
const MODES: &[&str] = &["flat", "left", "right"];
/// The run states by byte (`Status::state_name`).
const STATES: &[&str] = &["starting", "running", "safe mode", "faulted", "stopped"];
/// The reference kinds by byte (`Reference::HOLD`, `SINUSOID`, `EXCITATION`).
const KINDS: &[&str] = &["hold", "sinusoid", "excitation"];

/// Adds the names of `topic`'s enumeration bytes to its JSON object `o` (a byte out of range,
/// which validation refuses first, gets `"?"`).
fn add_names(topic: Topic, o: &mut serde_json::Map<String, Value>) {
    for &(t, field, name, values) in NAMES {
        if t == topic {
            let n = o.get(field).and_then(Value::as_u64);
            let v = n.and_then(|n| values.get(n as usize)).unwrap_or(&"?");
            o.insert(name.into(), Value::from(*v));
        }
    }
}

/// Removes the names from `topic`'s JSON object `o`, refusing one that does not name its byte
/// (the error names the field).
fn take_names(topic: Topic, o: &mut serde_json::Map<String, Value>) -> Result<(), FromJsonError> {
    for &(t, field, name, values) in NAMES {
        if t != topic {
            continue;
        }
        let Some(got) = o.remove(name) else { continue };
        let want = o
            .get(field)
            .and_then(Value::as_u64)
            .and_then(|n| values.get(n as usize));
        if want.is_none_or(|w| got != *w) {
            return Err(FromJsonError::Name(format!(
                "invalid `{name}` = {got}: `{field}` = {} is {}",
                o.get(field).unwrap_or(&Value::Null),
                want.map_or("out of range".to_owned(), |w| format!("\"{w}\"")),
            )));
        }
    }
    Ok(())
}

/// Foxglove's and Lichtblick's schema parsers take one JSON type per field and refuse the
/// channel otherwise ("Failed to parse channel schema"): a nullable field (`["number",
/// "null"]`, a rate a plant may not measure) becomes an optional `number`, left out of
/// `required`, and [`to_json`] leaves it out of the object when it is absent.
fn one_type_per_field(schema: &mut Value) {
    let mut optional = Vec::new();
    if let Some(props) = schema["properties"].as_object_mut() {
        for (name, p) in props.iter_mut() {
            if let Some(types) = p["type"].as_array() {
                let real: Vec<Value> = types.iter().filter(|t| *t != "null").cloned().collect();
                if real.len() == 1 && real.len() < types.len() {
                    p["type"] = real[0].clone();
                    optional.push(name.clone());
                }
            }
        }
    }
    if let Some(req) = schema["required"].as_array_mut() {
        req.retain(|r| !optional.iter().any(|o| r == o));
    }
}

/// Decodes and validates a wire payload of `topic` and returns its JSON object (UTF-8).
pub fn to_json(topic: Topic, wire: &[u8]) -> Result<Vec<u8>, DecodeError> {
    fn enc<T: Message + serde::Serialize>(wire: &[u8]) -> Result<Value, DecodeError> {
        let m: T = codec::decode(wire)?;
        // Serialising a struct of numbers and a string cannot fail. An absent (null) field is
        // left out: its schema names it optional ([`json_schema`]).
        let mut v = serde_json::to_value(&m).unwrap_or_default();
        if let Some(o) = v.as_object_mut() {
            o.retain(|_, x| !x.is_null());
        }
        Ok(v)
    }
    let mut v = match topic {
        Topic::State => enc::<PlantState>(wire),
        Topic::Torque => enc::<TorqueCommand>(wire),
        Topic::Event => enc::<ModeEvent>(wire),
        Topic::Status => enc::<Status>(wire),
        Topic::Reference => {
            let m: AnyReference = codec::decode(wire)?;
            let mut v = serde_json::to_value(ReferenceJson::from(&m)).unwrap_or_default();
            if let Some(o) = v.as_object_mut() {
                o.retain(|_, x| !x.is_null());
            }
            Ok(v)
        }
    }?;
    if let Some(o) = v.as_object_mut() {
        add_names(topic, o);
    }
    Ok(serde_json::to_vec(&v).unwrap_or_default())
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
    /// A name that does not name its byte (`mode_name` `"left"` with `mode` 2).
    #[error("{0}")]
    Name(String),
    /// A reference with the fields of neither layout, or of both ([`ReferenceJson`]).
    #[error("{0}")]
    Layout(String),
}

/// The wire payload of a JSON object of `topic`: the inverse of [`to_json`], byte for byte
/// (JSON numbers are written in shortest round-trip form and parsed correctly rounded, and the
/// wire encoding of a message is unique), after the message's own validation.
pub fn from_json(topic: Topic, json: &[u8]) -> Result<Vec<u8>, FromJsonError> {
    fn dec<T: Message + serde::de::DeserializeOwned>(v: Value) -> Result<Vec<u8>, FromJsonError> {
        let m: T = serde_json::from_value(v)?;
        m.validate()?;
        Ok(codec::encode(&m))
    }
    let mut v: Value = serde_json::from_slice(json)?;
    if let Some(o) = v.as_object_mut() {
        take_names(topic, o)?;
    }
    match topic {
        Topic::State => dec::<PlantState>(v),
        Topic::Torque => dec::<TorqueCommand>(v),
        Topic::Event => dec::<ModeEvent>(v),
        Topic::Status => dec::<Status>(v),
        Topic::Reference => {
            let j: ReferenceJson = serde_json::from_value(v)?;
            let m = j.into_message()?;
            m.validate()?;
            Ok(codec::encode(&m))
        }
    }
}

/// The JSON form of the reference topic's message, either layout (the module's
/// documentation): `kind`, `amplitude` and `omega` always; the paper's five gains for a
/// `Reference` (57 bytes), or `law` and `parameters` for a `LawReference` (107 bytes).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ReferenceJson {
    /// The trajectory: 0 hold `beta_d = pi/2`, 1 sinusoid, 2 excitation (a `Reference`'s
    /// `kind`, a `LawReference`'s `trajectory`).
    pub kind: u8,
    /// Sinusoid amplitude (the excitation's bound), rad (ignored for hold).
    pub amplitude: f64,
    /// Sinusoid angular frequency (the excitation's base), rad/s.
    pub omega: f64,
    /// The paper's law (a 57-byte `Reference` only): proportional gain, 1/s².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kp: Option<f64>,
    /// The paper's law only: derivative gain, 1/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kd: Option<f64>,
    /// The paper's law only: energy-adaptation gain `k`, 1/(J s²).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k: Option<f64>,
    /// The paper's law only: the energy the adaptation tracks, `E_av`, J.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub energy_avg: Option<f64>,
    /// The paper's law only: torque limit, N m (0 for none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub torque_limit: Option<f64>,
    /// Any law (a 107-byte `LawReference` only): its name, as in the controller's registry
    /// (`plain-pd`, `computed-torque`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub law: Option<String>,
    /// Any law only: its parameters in the order of its list (0 to 8), each in the unit that
    /// law documents.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parameters: Option<Vec<f64>>,
}

impl From<&AnyReference> for ReferenceJson {
    fn from(m: &AnyReference) -> Self {
        let none = Self {
            kind: 0,
            amplitude: 0.0,
            omega: 0.0,
            kp: None,
            kd: None,
            k: None,
            energy_avg: None,
            torque_limit: None,
            law: None,
            parameters: None,
        };
        match m {
            AnyReference::Paper(r) => Self {
                kind: r.kind,
                amplitude: r.amplitude,
                omega: r.omega,
                kp: Some(r.kp),
                kd: Some(r.kd),
                k: Some(r.k),
                energy_avg: Some(r.energy_avg),
                torque_limit: Some(r.torque_limit),
                ..none
            },
            AnyReference::Law(l) => Self {
                kind: l.trajectory,
                amplitude: l.amplitude,
                omega: l.omega,
                law: Some(l.law.clone()),
                parameters: Some(l.parameters.clone()),
                ..none
            },
        }
    }
}

impl ReferenceJson {
    /// The message of this JSON: a `Reference` when the five gains are given and neither
    /// `law` nor `parameters`, a `LawReference` when `law` and `parameters` are given and none
    /// of the gains; else an error naming the fields.
    pub fn into_message(self) -> Result<AnyReference, FromJsonError> {
        let gains = [self.kp, self.kd, self.k, self.energy_avg, self.torque_limit];
        match (gains, self.law, self.parameters) {
            ([Some(kp), Some(kd), Some(k), Some(energy_avg), Some(torque_limit)], None, None) => {
                Ok(AnyReference::Paper(Reference {
                    kind: self.kind,
                    amplitude: self.amplitude,
                    omega: self.omega,
                    kp,
                    kd,
                    k,
                    energy_avg,
                    torque_limit,
                }))
            }
            ([None, None, None, None, None], Some(law), Some(parameters)) => {
                Ok(AnyReference::Law(LawReference {
                    trajectory: self.kind,
                    amplitude: self.amplitude,
                    omega: self.omega,
                    law,
                    parameters,
                }))
            }
            _ => Err(FromJsonError::Layout(
                "invalid reference: give either all of `kp`, `kd`, `k`, `energy_avg`, \
                 `torque_limit` (the paper's law, a Reference) or `law` and `parameters` \
                 (any law, a LawReference), not both nor part of either"
                    .into(),
            )),
        }
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
                    alpha_dot: Some(-0.2),
                    beta_dot: Some(0.3),
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
            (
                Topic::Reference,
                encode(&LawReference {
                    trajectory: Reference::SINUSOID,
                    amplitude: 0.25,
                    omega: 1.0 / 3.0,
                    law: "plain-pd".into(),
                    parameters: vec![400.0, -0.0, 5e-324],
                }),
            ),
        ]
    }

    /// The schema lists exactly the JSON's fields, with matching JSON types, and every field
    /// is required: a message or schema edited alone fails here.
    #[test]
    fn schemas_match_the_json() {
        // The fields seen per topic, over its samples (the reference's two layouts).
        let mut seen: std::collections::BTreeMap<Topic, std::collections::BTreeSet<String>> =
            Default::default();
        for (topic, wire) in samples() {
            let v: Value = serde_json::from_slice(&to_json(topic, &wire).unwrap()).unwrap();
            let obj = v.as_object().unwrap();
            let schema = json_schema(topic);
            let props = schema["properties"].as_object().unwrap();
            let mut a: Vec<_> = obj.keys().collect();
            a.sort();
            seen.entry(topic)
                .or_default()
                .extend(a.iter().map(|k| k.to_string()));
            for k in &a {
                assert!(
                    props.contains_key(k.as_str()),
                    "{topic}.{k}: not in the schema"
                );
            }
            for (k, val) in obj {
                let p = &props[k];
                // One JSON type per field, as Foxglove's and Lichtblick's parsers require.
                let ty = p["type"]
                    .as_str()
                    .unwrap_or_else(|| panic!("{topic}.{k}: {p}"));
                let ok = match ty {
                    "integer" => val.is_u64(),
                    "number" => val.is_number(),
                    "string" => val.is_string(),
                    // A fixed-size array (`x_before`) or a list (`parameters`).
                    "array" => val.as_array().is_some_and(|a| {
                        let n = a.len() as u64;
                        p["minItems"].as_u64().unwrap_or(0) <= n
                            && p["maxItems"].as_u64().is_none_or(|m| n <= m)
                            && a.iter().all(Value::is_number)
                            && p["items"]["type"] == "number"
                    }),
                    _ => false,
                };
                assert!(ok, "{topic}.{k}: {val} is not a {ty}: {p}");
                // Every field is documented (units included).
                assert!(
                    p["description"].as_str().is_some_and(|d| !d.is_empty()),
                    "{topic}.{k}: {p}"
                );
            }
            let mut required: Vec<_> = schema["required"]
                .as_array()
                .unwrap()
                .iter()
                .map(|r| r.as_str().unwrap())
                .collect();
            required.sort();
            // Every field is required but the rates a plant may not measure and the fields of
            // one layout of the reference.
            let optional: &[&str] = match topic {
                Topic::State => &["alpha_dot", "beta_dot"],
                Topic::Reference => &[
                    "kp",
                    "kd",
                    "k",
                    "energy_avg",
                    "torque_limit",
                    "law",
                    "parameters",
                ],
                _ => &[],
            };
            let fields: Vec<&str> = a
                .iter()
                .map(|k| k.as_str())
                .filter(|k| !optional.contains(k))
                .collect();
            assert_eq!(required, fields, "{topic}: every field is required");
            assert_eq!(schema["additionalProperties"], false, "{topic}");
            assert_eq!(schema["title"], schema_name(topic));
            assert_eq!(schema["type"], "object");
        }
        // Every field of a schema is in some sample's JSON.
        for t in Topic::ALL {
            let schema = json_schema(t);
            let props: std::collections::BTreeSet<String> = schema["properties"]
                .as_object()
                .unwrap()
                .keys()
                .cloned()
                .collect();
            assert_eq!(seen[&t], props, "{t}");
        }
    }

    /// The strict check of a schema as Foxglove's and Lichtblick's parsers read it: anywhere in
    /// it, `type` is one of the JSON types as a single string (no list, no `null`), and no
    /// `anyOf`/`oneOf` of alternatives.
    #[test]
    fn every_schema_has_one_type_per_node() {
        fn walk(v: &Value, at: &str) {
            match v {
                Value::Object(o) => {
                    if let Some(t) = o.get("type") {
                        let ok = t.as_str().is_some_and(|t| {
                            ["object", "number", "integer", "string", "array", "boolean"]
                                .contains(&t)
                        });
                        assert!(ok, "{at}: type {t}");
                    }
                    for bad in ["anyOf", "oneOf"] {
                        assert!(!o.contains_key(bad), "{at}: {bad}");
                    }
                    for (k, x) in o {
                        walk(x, &format!("{at}/{k}"));
                    }
                }
                Value::Array(a) => a.iter().for_each(|x| walk(x, at)),
                _ => {}
            }
        }
        for t in Topic::ALL {
            walk(&json_schema(t), &schema_name(t));
        }
    }

    /// A state without rates leaves them out of its JSON (never 0), and reads back without
    /// rates; the JSON goes back to the same wire bytes.
    #[test]
    fn absent_rates_are_left_out_of_the_json() {
        let s = PlantState {
            seq: 4,
            time: 0.004,
            alpha: 0.01,
            beta: 1.5,
            alpha_dot: None,
            beta_dot: None,
            mode: 1,
        };
        let wire = encode(&s);
        let v: Value = serde_json::from_slice(&to_json(Topic::State, &wire).unwrap()).unwrap();
        assert!(
            v.get("alpha_dot").is_none() && v.get("beta_dot").is_none(),
            "{v}"
        );
        assert_eq!(v["alpha"].as_f64(), Some(0.01));
        let back: PlantState =
            codec::decode(&from_json(Topic::State, &serde_json::to_vec(&v).unwrap()).unwrap())
                .unwrap();
        assert_eq!(back, s);
        assert_eq!(
            from_json(Topic::State, &serde_json::to_vec(&v).unwrap()).unwrap(),
            wire
        );
        let schema = json_schema(Topic::State);
        assert_eq!(schema["properties"]["beta_dot"]["type"], "number");
        assert!(!schema["required"]
            .as_array()
            .unwrap()
            .iter()
            .any(|r| r == "beta_dot"));
    }

    #[test]
    fn json_round_trips_the_floats_exactly() {
        let s = PlantState {
            seq: 1,
            time: 0.1 + 0.2,
            alpha: 1e-300,
            beta: std::f64::consts::FRAC_PI_2,
            alpha_dot: Some(-0.0),
            beta_dot: Some(1.0 / 3.0),
            mode: 0,
        };
        let json = to_json(Topic::State, &encode(&s)).unwrap();
        let back: PlantState = codec::decode(&from_json(Topic::State, &json).unwrap()).unwrap();
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
            alpha_dot: Some(f64::MAX),
            beta_dot: Some(-f64::MIN_POSITIVE),
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

    /// Every enumeration byte has its name next to it, the names are the ones the rest of the
    /// code uses (`Mode::as_str`, `Status::state_name`), and a name that contradicts its byte is
    /// refused naming the field.
    #[test]
    fn enumerations_carry_their_names() {
        for (topic, wire) in samples() {
            let v: Value = serde_json::from_slice(&to_json(topic, &wire).unwrap()).unwrap();
            for &(t, field, name, values) in NAMES.iter().filter(|n| n.0 == topic) {
                let n = v[field].as_u64().unwrap() as usize;
                assert_eq!(v[name], values[n], "{t}.{name}");
            }
        }
        for (i, m) in MODES.iter().enumerate() {
            assert_eq!(tilting_proto::Mode::try_from(i as u8).unwrap().as_str(), *m);
        }
        for (i, st) in STATES.iter().enumerate() {
            let s = Status {
                state: i as u8,
                ..Status::default()
            };
            assert_eq!(s.state_name(), *st);
        }
        let kinds = [Reference::HOLD, Reference::SINUSOID, Reference::EXCITATION];
        assert_eq!(kinds.map(usize::from), [0, 1, 2]);
        assert_eq!(KINDS.len(), 3);
        let (_, wire) = &samples()[0];
        let mut v: Value = serde_json::from_slice(&to_json(Topic::State, wire).unwrap()).unwrap();
        assert_eq!(v["mode_name"], "left");
        v["mode_name"] = "right".into();
        let e = from_json(Topic::State, &serde_json::to_vec(&v).unwrap())
            .unwrap_err()
            .to_string();
        assert!(e.contains("`mode_name`") && e.contains("\"left\""), "{e}");
        // Without the names (an older recording) the JSON still reads.
        let o = v.as_object_mut().unwrap();
        o.remove("mode_name");
        assert_eq!(
            &from_json(Topic::State, &serde_json::to_vec(&v).unwrap()).unwrap(),
            wire
        );
    }

    /// The reference topic's two layouts: a `LawReference` shows its law's name and
    /// parameters (and no gains), a `Reference` its five gains (and no name); each JSON goes
    /// back to its own layout's bytes (107 and 57), and a JSON with the fields of both or of
    /// neither is refused naming them.
    #[test]
    fn both_reference_layouts_show_their_law_and_keep_their_bytes() {
        let law = LawReference {
            trajectory: Reference::HOLD,
            amplitude: 0.0,
            omega: 0.0,
            law: "plain-pd".into(),
            parameters: vec![400.0, 56.56],
        };
        let wire = encode(&law);
        assert_eq!(wire.len(), LawReference::SIZE);
        let v: Value = serde_json::from_slice(&to_json(Topic::Reference, &wire).unwrap()).unwrap();
        assert_eq!(v["law"], "plain-pd");
        assert_eq!(v["parameters"], serde_json::json!([400.0, 56.56]));
        assert_eq!(v["kind_name"], "hold");
        assert!(v.get("kp").is_none(), "{v}");
        let back = from_json(Topic::Reference, &serde_json::to_vec(&v).unwrap()).unwrap();
        assert_eq!(back, wire);
        // The paper's law by name in the generic layout stays 107 bytes, not the 57 of the
        // paper's own layout with the same numbers.
        let paper = Reference {
            kind: Reference::HOLD,
            amplitude: 0.0,
            omega: 0.0,
            kp: 100.0,
            kd: 14.14,
            k: 500.0,
            energy_avg: 20.0,
            torque_limit: 0.0,
        };
        let generic = encode(&LawReference::from(&paper));
        let j = to_json(Topic::Reference, &generic).unwrap();
        assert_eq!(from_json(Topic::Reference, &j).unwrap(), generic);
        let short = encode(&paper);
        let j = to_json(Topic::Reference, &short).unwrap();
        assert_eq!(from_json(Topic::Reference, &j).unwrap(), short);
        assert_eq!((short.len(), generic.len()), (57, 107));
        // Both layouts' fields, or part of one: refused, naming the fields.
        let mut both = v.clone();
        both["kp"] = 1.0.into();
        let mut part = serde_json::from_slice::<Value>(&j).unwrap();
        part.as_object_mut().unwrap().remove("kd");
        for bad in [both, part] {
            let e = from_json(Topic::Reference, &serde_json::to_vec(&bad).unwrap())
                .unwrap_err()
                .to_string();
            assert!(e.contains("`kp`") && e.contains("`parameters`"), "{e}");
        }
        // The law's own checks: a parameter that is not finite has no JSON, nine have no
        // wire form.
        let mut nine = v.clone();
        nine["parameters"] = serde_json::json!(vec![0.0; 9]);
        let e = from_json(Topic::Reference, &serde_json::to_vec(&nine).unwrap())
            .unwrap_err()
            .to_string();
        assert!(e.contains("count"), "{e}");
    }

    #[test]
    fn a_payload_that_does_not_decode_is_refused() {
        assert!(to_json(Topic::State, &[1, 2, 3]).is_err());
    }
}
