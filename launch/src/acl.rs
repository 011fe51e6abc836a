//! Secure deployment: a development certificate authority, one certificate per node, and the
//! zenoh configuration files that turn on mutual TLS and access control (`tilting certs`,
//! `tilting live --secure`, `tilting-router`).
//!
//! Everything here is zenoh's own machinery, configured: the `tls` link with `enable_mtls`
//! authenticates both ends of every link with a certificate signed by the robot's CA, and the
//! router's `access_control` block (default deny) matches each link's certificate common name
//! against the identities below and lets each identity publish only its own keys:
//!
//! | identity (CN `{robot}-{node}`) | may put | may declare a liveliness token |
//! |---|---|---|
//! | `plant` | `plant/state`, `plant/event`, `plant/status` | `alive/plant` |
//! | `controller` | `controller/torque` | `alive/controller` |
//! | `planner` | `planner/reference` (and reply to queries on it) | `alive/planner` |
//! | `logger` | nothing | nothing |
//!
//! All four may subscribe to, query and watch the liveliness of `tilting/{robot}/**`; a
//! certificate with any other common name (signed by the same CA or not) may do nothing.
//!
//! Zenoh applies ACL in the session that holds the configuration, on the messages crossing
//! its own links. Peers that find each other by gossip talk directly and never cross the
//! ACL of a third peer, so no session scouts, and every session that accepts links holds
//! rules: the router's for its **clients** (the planner, loggers, outside peers), and in the
//! direct topology of `live --secure` each **peer**'s own ([`node_acl`]): the plant's, the
//! controller's and the recorder's ([`RECORDER`]), which take the loop's messages from each
//! other on links of their own, so that the router relays none of them.

use crate::certs::{common_name, NODES};
use crate::session::RECORDER;
use serde_json::{json, Value};
use tilting_proto::Keys;

/// One allow rule of a zenoh ACL: `id`, the flows (`ingress`/`egress`), the message kinds and
/// the key expressions it covers.
fn acl_rule(id: &str, flows: &[&str], messages: &[&str], key_exprs: Vec<&str>) -> Value {
    json!({ "id": id, "permission": "allow", "flows": flows, "messages": messages,
            "key_exprs": key_exprs })
}

/// A subject of a zenoh ACL: the certificates' common names it matches.
fn acl_subject(id: &str, cns: Vec<String>) -> Value {
    json!({ "id": id, "cert_common_names": cns })
}

/// A policy of a zenoh ACL: which rules apply to which subjects.
fn acl_policy(id: &str, rules: &[&str], subjects: &[&str]) -> Value {
    json!({ "id": id, "rules": rules, "subjects": subjects })
}

/// The rules every authenticated identity of the robot gets, in the router's ACL and in each
/// node's own: "listen" (subscribe, query, watch tokens: ingress) and "receive" (get what it
/// listens to: egress), both on `all` (`tilting/<robot>/**`).
fn listen_rules(all: &str) -> [Value; 2] {
    [
        acl_rule(
            "listen",
            &["ingress"],
            &[
                "declare_subscriber",
                "query",
                "liveliness_query",
                "declare_liveliness_subscriber",
            ],
            vec![all],
        ),
        acl_rule(
            "receive",
            &["egress"],
            &[
                "put",
                "delete",
                "declare_subscriber",
                "query",
                "reply",
                "declare_queryable",
                "liveliness_token",
                "liveliness_query",
                "declare_liveliness_subscriber",
            ],
            vec![all],
        ),
    ]
}

/// The ingress rules `node` (one of [`DIRECT`]) enforces on its own links in the direct loop
/// (zenoh applies ACL only in the session that holds it: eclipse-zenoh/zenoh#2137). Every
/// identity of the robot (the router's included) may subscribe, query and watch tokens, and
/// receive what it subscribed to; beyond that, default deny:
///
/// - the plant accepts torques and the controller's token **only from the controller's
///   identity**, so only on the direct link (the router's copies are refused);
/// - the controller accepts states, events, statuses and the plant's token only from the
///   plant's identity, and the reference (puts, replies, queryable, the planner's token) only
///   from the router's, which let only the planner's identity publish it;
/// - the recorder ([`RECORDER`]) accepts states, events, statuses and the plant's token only
///   from the plant's identity, torques and the controller's token only from the controller's,
///   and nothing else (it takes the reference from its own planner session).
pub fn node_acl(keys: &Keys, node: &str, nodes: &[String]) -> Value {
    let robot = keys.robot();
    let all = format!("tilting/{robot}/**");
    let rule = acl_rule;
    let subject = acl_subject;
    let policy = acl_policy;
    let mut listeners: Vec<String> = nodes
        .iter()
        .filter(|n| NODES.contains(&n.as_str()) || n.starts_with("logger"))
        .map(|n| common_name(robot, n))
        .collect();
    listeners.sort();
    let mut rules = listen_rules(&all).to_vec();
    let mut subjects = vec![subject("robot", listeners)];
    let mut policies = vec![policy(
        "everyone listens",
        &["listen", "receive"],
        &["robot"],
    )];
    let states = rule(
        "states",
        &["ingress"],
        &["put", "liveliness_token"],
        vec![
            keys.plant_state(),
            keys.plant_event(),
            keys.plant_status(),
            keys.alive_plant(),
        ],
    );
    if node == RECORDER {
        rules.push(states);
        rules.push(rule(
            "torques",
            &["ingress"],
            &["put", "liveliness_token"],
            vec![keys.controller_torque(), keys.alive_controller()],
        ));
        subjects.push(subject("plant", vec![common_name(robot, "plant")]));
        subjects.push(subject(
            "controller",
            vec![common_name(robot, "controller")],
        ));
        policies.push(policy("plant", &["states"], &["plant"]));
        policies.push(policy("controller", &["torques"], &["controller"]));
    } else if node == "plant" {
        rules.push(rule(
            "torques",
            &["ingress"],
            &["put", "liveliness_token"],
            vec![keys.controller_torque(), keys.alive_controller()],
        ));
        subjects.push(subject(
            "controller",
            vec![common_name(robot, "controller")],
        ));
        policies.push(policy("controller", &["torques"], &["controller"]));
    } else {
        rules.push(states);
        rules.push(rule(
            "reference",
            &["ingress"],
            &["put", "reply", "declare_queryable", "liveliness_token"],
            vec![keys.planner_reference(), keys.alive_planner()],
        ));
        subjects.push(subject("plant", vec![common_name(robot, "plant")]));
        subjects.push(subject("router", vec![common_name(robot, "router")]));
        policies.push(policy("plant", &["states"], &["plant"]));
        policies.push(policy("router", &["reference"], &["router"]));
    }
    json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    })
}

/// The `access_control` block for `keys`' robot (see the module documentation).
pub fn acl(keys: &Keys, nodes: &[String]) -> Value {
    let robot = keys.robot();
    let all = format!("tilting/{robot}/**");
    let rule = acl_rule;
    let [listen, receive] = listen_rules(&all);
    let rules = vec![
        listen,
        receive,
        rule(
            "plant publishes",
            &["ingress"],
            &["put"],
            vec![keys.plant_state(), keys.plant_event(), keys.plant_status()],
        ),
        rule(
            "plant token",
            &["ingress"],
            &["liveliness_token"],
            vec![keys.alive_plant()],
        ),
        rule(
            "controller publishes",
            &["ingress"],
            &["put"],
            vec![keys.controller_torque()],
        ),
        rule(
            "controller token",
            &["ingress"],
            &["liveliness_token"],
            vec![keys.alive_controller()],
        ),
        rule(
            "planner publishes",
            &["ingress"],
            &["put", "declare_queryable", "reply"],
            vec![keys.planner_reference()],
        ),
        rule(
            "planner token",
            &["ingress"],
            &["liveliness_token"],
            vec![keys.alive_planner()],
        ),
    ];
    let listeners: Vec<String> = nodes
        .iter()
        .filter(|n| {
            n.as_str() != "router" && (NODES.contains(&n.as_str()) || n.starts_with("logger"))
        })
        .map(|n| common_name(robot, n))
        .collect();
    let subject = acl_subject;
    let subjects = vec![
        subject("nodes", listeners),
        subject("plant", vec![common_name(robot, "plant")]),
        subject("controller", vec![common_name(robot, "controller")]),
        subject("planner", vec![common_name(robot, "planner")]),
    ];
    let policy = acl_policy;
    json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": [
            policy("everyone listens", &["listen", "receive"], &["nodes"]),
            policy("plant", &["plant publishes", "plant token"], &["plant"]),
            policy("controller", &["controller publishes", "controller token"], &["controller"]),
            policy("planner", &["planner publishes", "planner token"], &["planner"]),
        ],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::certs::{generate, DEFAULT_ROUTER_ENDPOINT};
    use crate::config::direct_config;
    use crate::session::DIRECT;

    /// Whether `acl` (an `access_control` block) lets the certificate `cn` send `message` on
    /// `key` in `flow`: an allow rule of a policy whose subject names `cn` covers it (our rules
    /// use exact keys and `prefix/**` only); default deny otherwise.
    fn allows(acl: &Value, cn: &str, flow: &str, message: &str, key: &str) -> bool {
        let has = |v: &Value, x: &str| v.as_array().unwrap().iter().any(|e| e == x);
        let covers = |v: &Value| {
            v.as_array().unwrap().iter().any(|k| {
                let k = k.as_str().unwrap();
                k == key || k.strip_suffix("**").is_some_and(|p| key.starts_with(p))
            })
        };
        let subjects: Vec<&str> = acl["subjects"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|s| has(&s["cert_common_names"], cn))
            .map(|s| s["id"].as_str().unwrap())
            .collect();
        acl["policies"].as_array().unwrap().iter().any(|p| {
            subjects.iter().any(|s| has(&p["subjects"], s))
                && acl["rules"].as_array().unwrap().iter().any(|r| {
                    has(&p["rules"], r["id"].as_str().unwrap())
                        && has(&r["flows"], flow)
                        && has(&r["messages"], message)
                        && covers(&r["key_exprs"])
                })
        })
    }

    /// Each session of the direct topology takes each of the loop's topics from exactly the
    /// identity the module's table says publishes it (and the recorder takes no reference, as
    /// it never dials the router), and every identity of the robot may subscribe at each.
    /// Checked by evaluating the generated rules, against the table written out here.
    #[test]
    fn each_direct_session_takes_each_topic_from_its_publisher_only() {
        let dir = tempfile::tempdir().unwrap();
        let keys = Keys::new("unit").unwrap();
        let m = generate(
            &keys,
            dir.path(),
            &[],
            DEFAULT_ROUTER_ENDPOINT,
            &["rogue".into()],
        )
        .unwrap();
        let topics = [
            (keys.plant_state(), "plant"),
            (keys.plant_event(), "plant"),
            (keys.plant_status(), "plant"),
            (keys.controller_torque(), "controller"),
            (keys.planner_reference(), "router"),
        ];
        // Which topics each session takes at all (the ones it subscribes to).
        let takes = |node: &str, key: &str| match node {
            "plant" => key == keys.controller_torque(),
            "controller" => key != keys.controller_torque(),
            _ => key != keys.planner_reference(),
        };
        for node in DIRECT {
            let acl = direct_config(&keys, dir.path(), node, &m.nodes)["access_control"].clone();
            for cn in &m.nodes {
                let id = common_name("unit", cn);
                for (key, from) in topics {
                    let want = takes(node, key) && cn == from;
                    assert_eq!(
                        allows(&acl, &id, "ingress", "put", key),
                        want,
                        "{node} taking a put on {key} from {id}"
                    );
                }
                let listens = cn != "rogue";
                assert_eq!(
                    allows(
                        &acl,
                        &id,
                        "ingress",
                        "declare_subscriber",
                        keys.plant_state()
                    ),
                    listens,
                    "{node}: {id} subscribing"
                );
            }
        }
    }
}
