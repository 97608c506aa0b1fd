//! `magstand check` from the command line: a passing check file exits 0, a failing one exits
//! non-zero naming the check, the figure, the limit and the measured value; the JUnit XML
//! carries every element CI servers require; a check that cannot run is refused before any run
//! with nothing written; the JUnit file is byte-identical at 1 and 2 threads.
use std::path::Path;

mod common;
use common::magstand;

/// A short stair of the paper's tables, without the rigid body: seconds per run.
const QUICK: &str = r#"scenario = "builtin:czyba2015-tables"
set = ["program.dwell_s=1.0", "stand.enabled=false"]
runs = 3
seed = 11
"#;

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_string()
}

fn checks(rmse_max: f64, mot_z: [f64; 2]) -> String {
    format!(
        "[[check]]\nname = \"accuracy\"\nmethod = \"global-weighted\"\n{QUICK}rmse_ut.max = {rmse_max}\nmse_crlb_ratio.max = 50\n\n\
         [[check]]\nname = \"export\"\n{QUICK}export.ardupilot.COMPASS_MOT_Z = [{}, {}]\n",
        mot_z[0], mot_z[1]
    )
}

#[test]
fn a_passing_file_exits_0_and_a_failing_one_names_what_failed() {
    let dir = tempfile::tempdir().unwrap();
    let pass = write(dir.path(), "pass.toml", &checks(5.0, [-1e6, 1e6]));
    let r = magstand(&["check", &pass, "--threads", "2"]);
    assert!(r.ok, "{}\n{}", r.stdout, r.stderr);
    assert!(
        r.stdout.contains("rmse_ut.max") && r.stdout.contains("all 4 limits of 2 checks hold"),
        "{}",
        r.stdout
    );

    let fail = write(dir.path(), "fail.toml", &checks(1e-6, [1e5, 1e6]));
    let junit = dir.path().join("out.xml");
    let r = magstand(&[
        "check",
        &fail,
        "--junit",
        junit.to_str().unwrap(),
        "--threads",
        "2",
    ]);
    assert!(!r.ok, "{}", r.stdout);
    for needle in [
        "check \"accuracy\": rmse_ut.max = ",
        "is not <= 0.000001",
        "check \"export\": export.ardupilot.COMPASS_MOT_Z = ",
        "is not in [100000, 1000000]",
        "2 of 4 limits failed",
    ] {
        assert!(r.stderr.contains(needle), "`{needle}` in {}", r.stderr);
    }
    // The failing run still writes its report, for the CI server to show.
    let xml = std::fs::read_to_string(&junit).unwrap();
    assert_eq!(xml.matches("<failure ").count(), 2, "{xml}");
}

#[test]
fn the_junit_report_has_the_elements_ci_servers_require() {
    let dir = tempfile::tempdir().unwrap();
    let file = write(dir.path(), "c.toml", &checks(1e-6, [-1e6, 1e6]));
    let junit = dir.path().join("report.xml");
    let r = magstand(&["check", &file, "--junit", junit.to_str().unwrap()]);
    assert!(!r.ok);
    let xml = std::fs::read_to_string(&junit).unwrap();
    let report = quick_junit::Report::deserialize_from_str(&xml)
        .unwrap_or_else(|e| panic!("not JUnit XML: {e}\n{xml}"));
    // The Jenkins/Ant schema's required parts: <testsuites> with counts, <testsuite name
    // tests failures errors>, <testcase name classname>, <failure message type>.
    assert_eq!((report.tests, report.failures, report.errors), (4, 1, 0));
    assert_eq!(report.test_suites.len(), 2);
    let suite = &report.test_suites[0];
    assert_eq!(suite.name.as_str(), "accuracy");
    assert_eq!((suite.tests, suite.failures, suite.errors), (3, 1, 0));
    for case in &suite.test_cases {
        assert_eq!(
            case.classname.as_ref().map(|c| c.as_str()),
            Some("accuracy")
        );
    }
    assert!(
        xml.starts_with("<?xml version=\"1.0\" encoding=\"UTF-8\"?>"),
        "{xml}"
    );
    for needle in [
        "<testsuites name=",
        "<testsuite name=\"accuracy\" tests=\"3\"",
        "<testcase name=\"rmse_ut.max &lt;= 0.000001\" classname=\"accuracy\"",
        "<failure message=\"rmse_ut.max = ",
        "type=\"limit exceeded\"",
        "<property name=\"seed\" value=\"11\"/>",
    ] {
        assert!(xml.contains(needle), "`{needle}` in {xml}");
    }
}

#[test]
fn a_check_that_cannot_run_is_refused_before_any_run() {
    let dir = tempfile::tempdir().unwrap();
    let junit = dir.path().join("report.xml");
    for (text, needles) in [
        (
            format!(
                "[[check]]\nname = \"good\"\n{QUICK}rmse_ut.max = 1\n[[check]]\nname = \"typo\"\n{QUICK}rmse.max = 1\n"
            ),
            vec!["check 2 (\"typo\")", "`rmse`", "unknown figure"],
        ),
        (
            format!(
                "[[check]]\nname = \"ratio\"\nmethod = \"default\"\n{QUICK}crlb_ratio.max = 1\n"
            ),
            vec!["check 1 (\"ratio\")", "`crlb_ratio`", "no Cramer-Rao ratio"],
        ),
        (
            "[[check]]\nname = \"gone\"\nscenario = \"missing.toml\"\nruns = 2\nrmse_ut.max = 1\n"
                .to_string(),
            vec!["check 1 (\"gone\")", "`scenario`", "missing.toml"],
        ),
    ] {
        let file = write(dir.path(), "c.toml", &text);
        let start = std::time::Instant::now();
        let r = magstand(&["check", &file, "--junit", junit.to_str().unwrap()]);
        assert!(!r.ok, "accepted {text}");
        for n in needles {
            assert!(r.stderr.contains(n), "`{n}` in {}", r.stderr);
        }
        assert!(r.stdout.is_empty(), "ran something: {}", r.stdout);
        assert!(!junit.exists(), "wrote a report for a file that cannot run");
        // Refused while checking, not after runs (a run of QUICK takes seconds).
        assert!(start.elapsed().as_secs_f64() < 30.0);
    }
    // The report may not replace the check file it reads.
    let file = write(dir.path(), "c.toml", &checks(5.0, [-1e6, 1e6]));
    let r = magstand(&["check", &file, "--junit", &file]);
    assert!(!r.ok && r.stderr.contains("c.toml"), "{}", r.stderr);
    assert_eq!(
        std::fs::read_to_string(&file).unwrap(),
        checks(5.0, [-1e6, 1e6])
    );
}

#[test]
fn the_junit_report_is_byte_identical_at_1_and_2_threads() {
    let dir = tempfile::tempdir().unwrap();
    let text = format!(
        "{}\n[[check]]\nname = \"diagnosis\"\n{QUICK}diagnose.verdict = []\n",
        checks(5.0, [-1e6, 1e6])
    );
    let file = write(dir.path(), "c.toml", &text);
    let mut reports = Vec::new();
    for threads in ["1", "2"] {
        let junit = dir.path().join(format!("t{threads}.xml"));
        let r = magstand(&[
            "check",
            &file,
            "--junit",
            junit.to_str().unwrap(),
            "--threads",
            threads,
        ]);
        assert!(
            r.stderr.is_empty() || !r.stderr.contains("error: check"),
            "{}",
            r.stderr
        );
        reports.push(std::fs::read(&junit).unwrap());
    }
    assert!(
        reports[0] == reports[1],
        "1 thread:\n{}\n2 threads:\n{}",
        String::from_utf8_lossy(&reports[0]),
        String::from_utf8_lossy(&reports[1])
    );
}
