//! The fast slice of the parser fuzzing (issue 15): the generators of
//! `mrtwin_tests::fuzz` run a few thousand inputs per parser with a fixed seed; no input
//! may panic, hang or fail a property (a valid input rejected, a round trip broken, an
//! error without its file). The full campaign is `src/bin/fuzz-parsers.rs`.

use std::time::Duration;

use mrtwin_tests::fuzz::{parsers, run_campaign, CampaignOptions};

/// Inputs per parser: a few seconds in all in a release build.
const INPUTS: u64 = 3000;

#[test]
fn every_parser_survives_a_slice_of_the_fuzz_campaign() {
    let opts = CampaignOptions {
        inputs: INPUTS,
        seed: 15,
        threads: 2,
        hang_limit: Duration::from_secs(30),
        failures_dir: Some(std::env::temp_dir().join("mrtwin-fuzz-test-failures")),
    };
    let mut problems = Vec::new();
    for parser in parsers() {
        let r = run_campaign(&parser, &opts);
        assert_eq!(r.inputs, INPUTS, "{}", r.name);
        // The generators reach both sides: some inputs accepted, some rejected.
        assert!(r.accepted > 0 && r.rejected > 0, "{}: {r:?}", r.name);
        for f in &r.failures {
            problems.push(format!(
                "{} input {} ({}): {}{}",
                r.name,
                f.index,
                if f.panic { "panic" } else { "property" },
                f.message,
                f.saved
                    .as_ref()
                    .map(|d| format!(", saved in {}", d.display()))
                    .unwrap_or_default()
            ));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}
