//! Fuzzes the `sweep.json` parser of `forestlod report` (`parse_manifest`, issue 28) on raw
//! bytes. No input may panic; a refusal is one line naming the file; an accepted manifest keeps
//! the parser's promises (sizes in range, a name and a CSV, finite yaws) and, written back the
//! way `forestlod sweep` writes it, parses again to the same manifest. Seed:
//! `fuzz/seeds/sweep_json/` (a committed run's manifest).
#![no_main]

use forestlod_experiments::report::parse_manifest;
use libfuzzer_sys::fuzz_target;

const FILE: &str = "run/s/sweep.json";

fuzz_target!(|data: &[u8]| {
    // The report reads UTF-8 text only (`read_text_limited`); other bytes never reach the parser.
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match parse_manifest(text, FILE) {
        Ok(m) => {
            assert!((1..=16384).contains(&m.width) && (1..=16384).contains(&m.height));
            assert!(!m.name.trim().is_empty() && !m.csv.trim().is_empty());
            assert!(m.images.iter().all(|i| i.yaw_deg.is_finite()));
            // Written back, it parses; written back again, it parses to the same manifest. Not
            // equality after the first trip: serde_json (without its `float_roundtrip` feature)
            // may read an f64 of 17 significant digits one ulp off (the fuzzer found
            // 1.709722222222222 read back as 1.7097222222222221), so the first trip may move
            // a last bit; after it the manifest is a fixed point.
            let back = serde_json::to_string_pretty(&m).expect("an accepted manifest writes");
            let again = parse_manifest(&back, FILE).expect("a written-back manifest parses");
            let back2 = serde_json::to_string_pretty(&again).expect("writes");
            let third = parse_manifest(&back2, FILE).expect("a written-back manifest parses");
            assert_eq!(
                serde_json::to_value(&third).expect("writes"),
                serde_json::to_value(&again).expect("writes"),
                "a manifest changed on its way back"
            );
        }
        Err(e) => {
            let shown = e.to_string();
            assert!(shown.starts_with(FILE), "{shown}");
            assert_eq!(shown.lines().count(), 1, "{shown}");
        }
    }
});
