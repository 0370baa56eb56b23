//! Fuzzes the CSV instance-table parser (`parse_instances_csv`): no input may panic, and every
//! accepted row must satisfy the loader's contract (finite position, finite yaw, scale in
//! (0, 1000], a known species).
#![no_main]

use forestlod_reference::scene::builtin::Species;
use forestlod_reference::scene::load::parse_instances_csv;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let names: Vec<String> = Species::ALL.iter().map(|s| s.name().to_string()).collect();
    match parse_instances_csv(data, "fuzz.csv", &names) {
        Ok(rows) => {
            assert!(!rows.is_empty());
            for r in rows {
                assert!(r.position.iter().all(|c| c.is_finite()));
                assert!(r.yaw.is_finite());
                assert!(r.scale.is_finite() && r.scale > 0.0 && r.scale <= 1000.0);
                assert!((r.mesh as usize) < names.len());
            }
        }
        Err(e) => assert!(e.to_string().starts_with("fuzz.csv")),
    }
});
