//! The inputs the fuzzers found (`tests/fuzz_regressions/<target>/`), replayed through the same
//! fuzz target functions (`bevy_wii_deform_fuzz`) with the ordinary build: each must end in a
//! typed error or a valid result — no panic, and within a few seconds (the fuzzers allow one
//! second per input in release builds; the bound here only catches a hang).

use std::path::Path;
use std::sync::mpsc;
use std::time::Duration;

/// What an input may take here before it counts as a hang.
const HANG: Duration = Duration::from_secs(20);

#[test]
fn every_kept_fuzz_input_replays_without_a_panic_or_a_hang() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
    let mut replayed = 0;
    let mut failures = Vec::new();
    for target in std::fs::read_dir(&root).expect("tests/fuzz_regressions exists") {
        let target = target.unwrap().path();
        if !target.is_dir() {
            continue;
        }
        let name = target.file_name().unwrap().to_string_lossy().into_owned();
        assert!(
            bevy_wii_deform_fuzz::TARGETS
                .iter()
                .any(|(t, _)| *t == name),
            "tests/fuzz_regressions/{name} is not a fuzz target"
        );
        for input in std::fs::read_dir(&target).unwrap() {
            let input = input.unwrap().path();
            let bytes = std::fs::read(&input).unwrap();
            let (send, receive) = mpsc::channel();
            let target_name = name.clone();
            std::thread::spawn(move || {
                let outcome = std::panic::catch_unwind(|| {
                    bevy_wii_deform_fuzz::run(&target_name, &bytes);
                });
                let _ = send.send(outcome.is_ok());
            });
            let label = format!("{name}/{}", input.file_name().unwrap().to_string_lossy());
            match receive.recv_timeout(HANG) {
                Ok(true) => {}
                Ok(false) => failures.push(format!("{label}: panicked")),
                Err(_) => failures.push(format!("{label}: still running after {HANG:?}")),
            }
            replayed += 1;
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
    assert!(replayed > 0, "no kept inputs under {}", root.display());
}
