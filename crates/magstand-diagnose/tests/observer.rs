//! A diagnosis reports its stages to an observer as it runs (`magstand diagnose` shows them on
//! the terminal): the baseline, each round with its candidates, each candidate fitted, each
//! term refitted with the model, and the assembly, in that order and matching the rounds the
//! diagnosis records. Observing changes nothing: the diagnosis is the same, bit for bit.
mod common;
use std::sync::Mutex;

use common::{bench_supply_stair, diagnose_default};
use magstand_diagnose::{DiagnoseConfig, DiagnoseObserver, Stage, diagnose_observed};
use magstand_sim::simulate;

/// Keeps every stage it is told, in order.
#[derive(Default)]
struct Recorder(Mutex<Vec<Stage>>);

impl DiagnoseObserver for Recorder {
    fn stage(&self, stage: Stage) {
        self.0.lock().unwrap().push(stage);
    }
}

#[test]
fn the_stages_are_reported_in_order_and_change_nothing() {
    // A late magnetometer: a finding, so that a term is refitted with the model.
    let (nominal, real) = bench_supply_stair(&["logging.mag_delay_s=0.2"]);
    let rec = simulate(&real, 3);
    let plain = diagnose_default(&rec, "late.csv", &nominal);
    let recorder = Recorder::default();
    let config = DiagnoseConfig::default().check().unwrap();
    let observed = diagnose_observed(&rec, "late.csv", &nominal, &config, &recorder).unwrap();
    assert_eq!(
        format!("{observed:?}"),
        format!("{plain:?}"),
        "an observed diagnosis differs from the plain one"
    );
    assert_eq!(observed.verdict, ["time_offset"], "{}", observed.summary());

    let stages = recorder.0.into_inner().unwrap();
    assert_eq!(stages.first(), Some(&Stage::Baseline), "{stages:?}");
    assert_eq!(stages.last(), Some(&Stage::Assembling), "{stages:?}");
    // Each round as the diagnosis records it: its candidates (the catalog's forms; the
    // record adds any richer forms tried beside them), each fitted once, and the candidate
    // refitted with the model where the round took one in.
    let mut at = 1;
    for (k, round) in observed.rounds.iter().enumerate() {
        let Stage::Round {
            number, candidates, ..
        } = &stages[at]
        else {
            panic!("stage {at} is not round {}: {:?}", k + 1, stages[at]);
        };
        assert_eq!(*number, k + 1, "{stages:?}");
        let recorded: Vec<&str> = round.candidates.iter().map(|c| c.name.as_str()).collect();
        assert!(
            candidates.iter().all(|c| recorded.contains(&c.as_str())),
            "round {number}: reported {candidates:?}, recorded {recorded:?}"
        );
        at += 1;
        let mut fitted: Vec<&str> = Vec::new();
        for done in 1..=candidates.len() {
            let Stage::CandidateFitted { name, done: d, of } = &stages[at] else {
                panic!("stage {at} is not a fitted candidate: {:?}", stages[at]);
            };
            assert_eq!((*d, *of), (done, candidates.len()), "{:?}", stages[at]);
            fitted.push(name);
            at += 1;
        }
        let mut expected: Vec<&str> = candidates.iter().map(String::as_str).collect();
        fitted.sort_unstable();
        expected.sort_unstable();
        assert_eq!(fitted, expected, "round {number}");
        if let Stage::Refining { candidate } = &stages[at] {
            // Taken in: recorded as accepted, or as refused once refitted.
            let refused = round.candidates.iter().any(|c| {
                &c.name == candidate && c.note.as_deref().is_some_and(|n| n.starts_with("refused"))
            });
            assert!(
                round.accepted.as_ref() == Some(candidate) || refused,
                "round {number}: refitted with {candidate}, accepted {:?}",
                round.accepted
            );
            at += 1;
        } else {
            assert_eq!(round.accepted, None, "round {number}: no stage refitted it");
        }
    }
    assert_eq!(
        at,
        stages.len() - 1,
        "stages after the last round: {stages:?}"
    );
    assert!(
        stages
            .iter()
            .any(|s| matches!(s, Stage::Refining { candidate } if candidate == "time_offset")),
        "{stages:?}"
    );
}
