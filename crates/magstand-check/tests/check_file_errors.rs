//! A check that cannot run is an error before anything runs, naming the entry and the key:
//! unknown figures, statistics, methods, effects and parameters, a limit on a figure the
//! method does not have, missing settings, a scenario that does not load.
use magstand_check::{CheckError, CheckFile, Limit};
use std::path::Path;

const HEAD: &str = r#"
[[check]]
name = "quick"
scenario = "builtin:czyba2015-tables"
runs = 3
seed = 1
"#;

fn checked(text: &str) -> Result<magstand_check::ValidChecks, CheckError> {
    CheckFile::from_toml_str(text, "CHECKS.toml", Path::new("."))?.check()
}

fn refused(text: &str, key: &str, needle: &str) {
    match checked(text) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => {
            let m = e.to_string();
            assert!(
                m.contains("CHECKS.toml") && m.contains(&format!("`{key}`")) && m.contains(needle),
                "expected the file, key `{key}` and `{needle}` in: {m}\n{text}"
            );
        }
    }
}

#[test]
fn unknown_figures_statistics_and_names_are_refused_with_the_entry_and_key() {
    refused(&format!("{HEAD}rmse.max = 1"), "rmse", "unknown figure");
    refused(
        &format!("{HEAD}rmse_ut.p99 = 1"),
        "rmse_ut.p99",
        "unknown statistic",
    );
    refused(
        &format!("{HEAD}rmse_ut.max = \"1\""),
        "rmse_ut.max",
        "expected a number",
    );
    refused(&format!("{HEAD}rmse_ut.max = -1.0"), "rmse_ut.max", ">= 0");
    refused(&format!("{HEAD}rmse_ut = 1"), "rmse_ut", "table of limits");
    refused(
        &format!("{HEAD}failures.max = 0.5"),
        "failures.max",
        "whole number",
    );
    refused(
        &format!("{HEAD}diagnose.verdict = [\"gremlins\"]"),
        "diagnose.verdict",
        "unknown effect `gremlins`",
    );
    refused(
        &format!("{HEAD}diagnose.verdict = []\ndiagnose.extra = 1"),
        "diagnose.extra",
        "unknown key",
    );
    refused(
        &format!("{HEAD}export.ardupilot.COMPASS_MOT_W = [0, 1]"),
        "export.ardupilot.COMPASS_MOT_W",
        "unknown parameter",
    );
    refused(
        &format!("{HEAD}export.inav.X = [0, 1]"),
        "export.inav",
        "unknown autopilot",
    );
    refused(
        &format!("{HEAD}export.px4.CAL_MAG0_ZCOMP = [1, 0]"),
        "export.px4.CAL_MAG0_ZCOMP",
        "lo <= hi",
    );
}

#[test]
fn a_limit_on_a_figure_the_method_does_not_have_is_refused() {
    refused(
        &format!("{HEAD}method = \"automatic\"\nmse_crlb_ratio.max = 1.2"),
        "mse_crlb_ratio",
        "no Cramer-Rao ratio",
    );
    refused(
        &format!(
            "{HEAD}method = \"automatic-current\"\nset = [\"logging.record_power=false\"]\nrmse_ut.max = 1"
        ),
        "method",
        "current input",
    );
    refused(
        &format!("{HEAD}method = \"magic\"\nrmse_ut.max = 1"),
        "method",
        "`magic`",
    );
}

#[test]
fn missing_settings_and_scenarios_are_refused() {
    refused(
        "[[check]]\nname = \"a\"\nruns = 2\nrmse_ut.max = 1",
        "scenario",
        "missing",
    );
    refused(
        "[[check]]\nname = \"a\"\nscenario = \"no/such/stand.toml\"\nruns = 2\nrmse_ut.max = 1",
        "scenario",
        "no/such/stand.toml",
    );
    refused(
        "[[check]]\nname = \"a\"\nscenario = \"builtin:nope\"\nruns = 2\nrmse_ut.max = 1",
        "scenario",
        "no shipped scenario",
    );
    refused(
        "[[check]]\nname = \"a\"\nscenario = \"builtin:czyba2015-tables\"\nrmse_ut.max = 1",
        "runs",
        "missing",
    );
    refused(
        "[[check]]\nname = \"a\"\nscenario = \"builtin:czyba2015-tables\"\nruns = 1\nrmse_ut.max = 1",
        "runs",
        "1 is not allowed",
    );
    refused(HEAD, "name", "no limits");
    refused(
        &format!("{HEAD}rmse_ut.max = 1\n{HEAD}rmse_ut.max = 2"),
        "name",
        "another check has this name",
    );
    refused(
        &format!("{HEAD}set = [\"supply.nonsense=3\"]\nrmse_ut.max = 1"),
        "scenario",
        "nonsense",
    );
}

#[test]
fn a_file_without_checks_is_refused() {
    for text in ["", "title = \"x\"", "check = 3", "[check]\nname = \"a\""] {
        let e = checked(text)
            .err()
            .unwrap_or_else(|| panic!("accepted {text:?}"));
        assert!(
            matches!(e, CheckError::File { .. }) && e.to_string().contains("CHECKS.toml"),
            "{text:?}: {e}"
        );
    }
}

#[test]
fn a_valid_entry_gives_its_limits_with_failures_held_at_zero() {
    let checks = checked(&format!(
        "{HEAD}heading_deg.p95 = 0.5\nexport.ardupilot.COMPASS_MOT2_Z = [40, 260]"
    ))
    .unwrap();
    let keys: Vec<String> = checks.checks[0].limits.iter().map(Limit::key).collect();
    assert_eq!(
        keys,
        [
            "export.ardupilot.COMPASS_MOT2_Z",
            "heading_after_deg.p95",
            "failures.max"
        ]
    );
    assert!(matches!(
        checks.checks[0].limits[0],
        Limit::Parameter { instance: 2, .. }
    ));
    assert_eq!(checks.checks[0].method.id, "automatic");
}

#[test]
fn the_shipped_example_checks_the_paper_method_the_default_choice_and_an_ardupilot_export() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios/checks/example.toml");
    let checks = CheckFile::load(&path)
        .and_then(CheckFile::check)
        .unwrap_or_else(|e| panic!("{e}"));
    let methods: Vec<&str> = checks.checks.iter().map(|c| c.method_id.as_str()).collect();
    assert!(
        methods.contains(&"paper-local") && methods.contains(&"default"),
        "{methods:?}"
    );
    assert!(
        checks
            .checks
            .iter()
            .any(|c| c.limits.iter().any(|l| matches!(
                l,
                Limit::Parameter {
                    autopilot: magstand_logs::export::Autopilot::ArduPilot,
                    ..
                }
            )))
    );
    assert!(
        checks
            .checks
            .iter()
            .any(|c| c.scenario_spec == "builtin:czyba2015-stair")
    );
}

#[test]
fn the_files_a_check_reads_are_its_scenario_and_nominal_files_not_shipped_ones() {
    let dir = tempfile::tempdir().unwrap();
    let text = magstand_sim::builtin::get("thermal").unwrap();
    std::fs::write(dir.path().join("stand.toml"), text).unwrap();
    std::fs::write(dir.path().join("nominal.toml"), text).unwrap();
    let file = "[[check]]\nname = \"a\"\nscenario = \"stand.toml\"\nruns = 2\n\
                diagnose.verdict = []\ndiagnose.nominal = \"nominal.toml\"\n\
                [[check]]\nname = \"b\"\nscenario = \"builtin:thermal\"\nruns = 2\n\
                diagnose.verdict = []\n";
    let checks = CheckFile::from_toml_str(file, "CHECKS.toml", dir.path())
        .and_then(CheckFile::check)
        .unwrap();
    assert_eq!(
        checks.input_files(),
        [
            dir.path().join("stand.toml"),
            dir.path().join("nominal.toml")
        ]
    );
}
