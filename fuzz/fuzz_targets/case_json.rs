//! Fuzzes the `case.json` parser of `forestlod verify` (`parse_case_json`, issue 28): no input
//! may panic; an accepted case has a valid camera and parameters, a size within the frame limit
//! and at most `MAX_ALTERNATIVES` alternatives; a refused one is one line naming the file.
#![no_main]

use forestlod_experiments::case::{MAX_ALTERNATIVES, parse_case_json};
use forestlod_reference::output::MAX_FRAME_SIDE;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match parse_case_json(text, "case.json") {
        Ok(case) => {
            case.camera.validate().expect("an accepted camera validates");
            case.params.validate().expect("accepted parameters validate");
            assert!((1..=MAX_FRAME_SIDE).contains(&case.camera.width));
            assert!((1..=MAX_FRAME_SIDE).contains(&case.camera.height));
            assert!(case.alternatives <= MAX_ALTERNATIVES);
            assert!(case.commands <= u64::from(forestlod_reference::shared::MAX_COMMANDS));
        }
        Err(e) => {
            let line = e.to_string();
            assert!(line.starts_with("case.json: "), "{line}");
            assert!(!line.contains('\n'), "{line}");
        }
    }
});

