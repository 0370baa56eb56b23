//! Fuzzes the sweep-file parser (`parse_sweep_toml`, issue 28): pure, reads no file. No input may
//! panic or hang; a refusal is one line naming the file; an accepted sweep validates again (also
//! its `[quick]` view), builds a non-empty set of parameter sets and poses within the work limit,
//! and every parameter set passes the parameter table's validation.
#![no_main]

use forestlod_experiments::sweep::{MAX_SWEEP_FRAMES, parse_sweep_toml};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match parse_sweep_toml(text, "fuzz.toml") {
        Ok(spec) => {
            spec.validate("fuzz.toml").expect("an accepted sweep validates again");
            let sets = spec.param_sets("fuzz.toml").expect("its parameter sets build");
            let poses = spec.poses();
            assert!(!sets.is_empty() && !poses.is_empty());
            assert!((sets.len() * poses.len()) as u128 <= MAX_SWEEP_FRAMES);
            for s in &sets {
                s.params.validate().expect("every parameter set is valid");
            }
            let quick = spec.quick();
            quick.validate("fuzz.toml").expect("the [quick] view validates");
        }
        Err(e) => {
            let line = e.to_string();
            assert!(line.starts_with("fuzz.toml: "), "{line}");
            assert!(!line.contains('\n'), "{line}");
        }
    }
});
