//! A router's access rules (Zenoh's `access_control`), by role, from the identities it knows.
//!
//! Zenoh 1.10 matches a rule's subject on the exact common name of the link's certificate and
//! has no templating of keys by subject, so each edge gets rules of its own, written out from
//! its identity: it may publish only its own streams (and their zenoh-ext cache and heartbeat
//! sub-keys), subscribe only to its own push keys, answer queries on its own keys, and hold its
//! own liveliness tokens. A cloud may do anything under `risktwin/v1/`, pushes included; a
//! router, anything (it forwards for other routers). Anyone else (an unknown name) is denied
//! everything: the default. Rules are checked on both flows of each link, ingress (what the
//! link's holder sends) and egress (what it may be sent).

use super::Identity;
use crate::keyexpr::{self, CloudToEdge, EdgeReport, EdgeStream, ROOT};
use serde_json::{Value, json};

/// zenoh-ext's verbatim chunk: `**` never matches it, so every key that may carry an
/// advanced publisher's cache, heartbeat or token is written again with `/@adv/**`.
const ADV: &str = "@adv/**";

/// Every message kind Zenoh's access control knows.
const ALL_MESSAGES: [&str; 9] = [
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "declare_queryable",
    "reply",
    "liveliness_token",
    "declare_liveliness_subscriber",
    "liveliness_query",
];

/// The `access_control` section of a router's zenoh config: deny by default, allow per role.
pub fn access_control(identities: &[Identity]) -> Value {
    let mut rules = Vec::new();
    let mut subjects = Vec::new();
    let mut policies = Vec::new();
    let names = |keep: fn(&Identity) -> bool| -> Vec<String> {
        identities.iter().filter(|i| keep(i)).map(Identity::common_name).collect()
    };
    let root_all = vec![format!("{ROOT}/**"), format!("{ROOT}/**/{ADV}")];
    let role_rules: [(&str, Vec<String>, Vec<String>); 2] = [
        ("cloud", names(|i| matches!(i, Identity::Cloud { .. })), root_all.clone()),
        ("router", names(|i| matches!(i, Identity::Router { .. })), vec!["**".to_owned(), format!("**/{ADV}")]),
    ];
    for (role, common_names, keys) in role_rules {
        if common_names.is_empty() {
            continue;
        }
        let rule = format!("{role}-all");
        rules.push(rule_json(&rule, &ALL_MESSAGES, &["ingress", "egress"], &keys));
        subjects.push(json!({ "id": role, "cert_common_names": common_names }));
        policies.push(json!({ "rules": [rule], "subjects": [role] }));
    }
    for identity in identities {
        let Identity::Edge { site, id } = identity else { continue };
        let name = identity.common_name();
        let mut own: Vec<String> = EdgeStream::ALL.iter().map(|s| keyexpr::edge_stream(site, id, *s)).collect();
        own.push(keyexpr::edge_map(site, id));
        own.push(keyexpr::edge_report(site, id, EdgeReport::ScenarioResult));
        let own_adv: Vec<String> = own.iter().map(|k| format!("{k}/{ADV}")).collect();
        let alive = keyexpr::liveliness_token(site, id);
        // Its pushes and its delivery acknowledgements.
        let pushes: Vec<String> =
            [CloudToEdge::Scenario, CloudToEdge::Policy, CloudToEdge::Control, CloudToEdge::Warning, CloudToEdge::Ack]
                .iter()
                .map(|p| keyexpr::cloud_to_edge(site, id, *p))
                .collect();
        // The cloud's token, held per site or for every site (`*`).
        let cloud_alive = vec![keyexpr::cloud_liveliness(Some(site)), keyexpr::cloud_liveliness(None)];
        let edge_rules = [
            // Its own streams: samples, cache answers, heartbeats, tokens, cache queryables.
            ("publish", &["put", "reply", "liveliness_token"][..], "ingress", [own.clone(), own_adv.clone()].concat()),
            ("cache", &["declare_queryable"][..], "ingress", own_adv),
            ("alive", &["liveliness_token", "liveliness_query"][..], "ingress", vec![alive.clone()]),
            ("listen", &["declare_subscriber"][..], "ingress", pushes.clone()),
            ("watch-cloud", &["declare_liveliness_subscriber", "liveliness_query"][..], "ingress", cloud_alive.clone()),
            // What it may be sent: its pushes, the answer to its duplicate-id question, and
            // the metadata a publisher needs (who subscribes: matching; the cloud's recovery
            // queries to its cache, which name the cloud's wildcard, not the edge's key).
            ("receive", &["put"][..], "egress", pushes),
            ("told-alive", &["liveliness_token"][..], "egress", vec![alive]),
            ("cloud-alive", &["liveliness_token", "reply"][..], "egress", cloud_alive),
            (
                "matched",
                &["declare_subscriber", "query", "declare_liveliness_subscriber", "liveliness_query"][..],
                "egress",
                root_all.clone(),
            ),
        ];
        let mut rule_ids = Vec::new();
        for (what, messages, flow, keys) in edge_rules {
            let rule = format!("{name}/{what}");
            rules.push(rule_json(&rule, messages, &[flow], &keys));
            rule_ids.push(rule);
        }
        subjects.push(json!({ "id": name, "cert_common_names": [name] }));
        policies.push(json!({ "rules": rule_ids, "subjects": [name] }));
    }
    json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    })
}

fn rule_json(id: &str, messages: &[&str], flows: &[&str], keys: &[String]) -> Value {
    json!({ "id": id, "messages": messages, "flows": flows, "permission": "allow", "key_exprs": keys })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::keyexpr::{SiteId, SourceId};

    #[test]
    fn an_edge_is_allowed_its_own_keys_only_and_zenoh_accepts_the_rules() {
        let edge = Identity::Edge { site: SiteId::new("s1").unwrap(), id: SourceId::new("v1").unwrap() };
        let ids = [edge, Identity::Cloud { name: "c".into() }, Identity::Router { name: "r".into() }];
        let acl = access_control(&ids);
        let mut config = zenoh::Config::default();
        config.insert_json5("access_control", &acl.to_string()).expect("zenoh parses the rules");
        let rule = |id: &str| acl["rules"].as_array().unwrap().iter().find(|r| r["id"] == id).unwrap().clone();
        let publish = rule("edge:s1:v1/publish");
        let keys: Vec<&str> = publish["key_exprs"].as_array().unwrap().iter().map(|k| k.as_str().unwrap()).collect();
        assert!(keys.contains(&"risktwin/v1/s1/v1/state"));
        assert!(keys.contains(&"risktwin/v1/s1/v1/state/@adv/**"));
        assert!(keys.iter().all(|k| k.starts_with("risktwin/v1/s1/v1/")), "{keys:?}");
        assert!(!keys.iter().any(|k| k.ends_with("/policy") || k.ends_with("/scenario")), "{keys:?}");
        assert_eq!(rule("edge:s1:v1/receive")["flows"], json!(["egress"]));
        // Its delivery acknowledgements and the cloud's token reach it.
        assert!(rule("edge:s1:v1/receive")["key_exprs"].as_array().unwrap().contains(&json!("risktwin/v1/s1/v1/ack")));
        assert!(rule("edge:s1:v1/listen")["key_exprs"].as_array().unwrap().contains(&json!("risktwin/v1/s1/v1/ack")));
        let watch = rule("edge:s1:v1/watch-cloud");
        assert_eq!(watch["key_exprs"], json!(["risktwin/v1/s1/alive/cloud", "risktwin/v1/*/alive/cloud"]));
        assert_eq!(acl["subjects"][0]["cert_common_names"], json!(["cloud:c"]));
        assert_eq!(acl["default_permission"], "deny");
    }
}
