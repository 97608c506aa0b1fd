//! The demo's pipeline against the simulator's truth: on a battery-powered paper-like stair,
//! every named method is judged in order, and the automatic choice among families beats the
//! paper's fixed throttle model, whose structure cannot follow the battery's sag.
use magstand_sim::{Scenario, simulate};
use magstand_study::comparison::identify_and_compensate;

#[test]
fn the_chosen_family_beats_the_papers_model_on_a_sagging_battery() {
    let short = ["program.dwell_s=3.0".to_string()];
    let ident_s = Scenario::load_spec("builtin:czyba2015-stair", &short).unwrap();
    let mut down = short.to_vec();
    down.push("program.direction=\"down\"".into());
    let valid_s = Scenario::load_spec("builtin:czyba2015-stair", &down).unwrap();
    let (ident, valid) = (simulate(&ident_s, 1), simulate(&valid_s, 2));
    let methods: Vec<_> = magstand_ident::methods::catalog()
        .into_iter()
        .filter(|m| ["px4", "paper-local"].contains(&m.id))
        .collect();
    let c = identify_and_compensate(&methods, &ident, "ident", &valid, "valid").unwrap();
    let labels: Vec<_> = c.judged.iter().map(|j| j.label.as_str()).collect();
    assert_eq!(labels.len(), 3, "{labels:?}");
    assert_eq!(&labels[..2], [methods[0].label, methods[1].label]);
    assert!(labels[2].contains(c.chosen.family()), "{labels:?}");
    let truth = |k: usize| {
        let e = c.judged[k].evaluation.truth_rmse_ut.unwrap();
        (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt()
    };
    assert!(
        truth(2) < 0.5 * truth(1) && truth(1) < truth(0),
        "truth RMSE px4 {} paper {} chosen ({}) {}",
        truth(0),
        truth(1),
        c.chosen.family(),
        truth(2)
    );
}
