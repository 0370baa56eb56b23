//! Fuzzes the `case.toml` parser of `forestlod check --replay` (`parse_replay_toml`, issue 28): no
//! input may panic; an accepted case has a valid camera (eye at zero), valid parameters with a
//! finite eye, and no `refine` in its plan; a refused one is one line naming the file.
#![no_main]

use forestlod_experiments::check::parse_replay_toml;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match parse_replay_toml(text, "case.toml") {
        Ok(case) => {
            case.camera.validate().expect("an accepted camera validates");
            case.params.validate().expect("accepted parameters validate");
            assert!(case.eye.iter().all(|x| x.is_finite()));
            assert_eq!(case.camera.eye, [0.0; 3]);
        }
        Err(e) => {
            let line = e.to_string();
            assert!(line.starts_with("case.toml: "), "{line}");
            assert!(!line.contains('\n'), "{line}");
        }
    }
});
