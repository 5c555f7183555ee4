//! Provenance: every manifest says where its result came from, and
//! `results/README.md` is the index the manifests give today.

use dualphoton::io::manifest::write_manifest;
use dualphoton::io::results_index::{markdown, COMMAND, FILE};
use serde_json::Value;
use std::path::Path;

#[test]
fn the_results_index_is_current() {
    let results = Path::new(env!("CARGO_MANIFEST_DIR")).join("results");
    let wanted = markdown(&results).unwrap();
    let found = std::fs::read_to_string(results.join(FILE)).unwrap_or_default();
    assert!(found == wanted, "results/{FILE} is out of date with the manifests: run `{COMMAND}`");
}

#[test]
fn a_manifest_carries_its_provenance() {
    #[derive(serde::Serialize)]
    struct Settings {
        res: usize,
    }
    let path = std::env::temp_dir().join(format!("dualphoton-manifest-{}.json", std::process::id()));
    write_manifest(&path, &Settings { res: 16 }, 1.5).unwrap();
    let m: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    std::fs::remove_file(&path).unwrap();
    assert_eq!(m["res"], 16, "the settings");
    let revision = m["revision"].as_str().unwrap();
    assert!(revision == "unknown" || revision.len() >= 12 && revision.bytes().all(|b| b.is_ascii_hexdigit()));
    assert!(m["tree_clean"].is_boolean() || (m["tree_clean"].is_null() && revision == "unknown"), "{m}");
    let command = m["command"].as_str().unwrap();
    assert!(command.starts_with("provenance"), "the test binary's name first: {command}");
    let date = m["date"].as_str().unwrap().as_bytes();
    assert!(date.len() == 20 && date[4] == b'-' && date[10] == b'T' && date[19] == b'Z', "{}", m["date"]);
    assert!(m["date"].as_str().unwrap() >= "2025-01-01T00:00:00Z");
    assert_eq!(m["wall_s"], 1.5);
    assert!(m["threads"].as_u64().unwrap() >= 1);
    assert!(m.get("git").is_none(), "the revision at writing time is gone");
}
