//! The outcomes as JUnit XML, which GitHub Actions, GitLab CI and Jenkins show without
//! plugins: one test suite per check, one test case per limit. Durations and timestamps are
//! left out, so the same check file and seed give the same bytes on any machine and thread
//! count.
use quick_junit::{NonSuccessKind, Property, Report, TestCase, TestCaseStatus, TestSuite};

use crate::{CheckError, CheckOutcome};

/// The outcomes of the checks of `origin` as JUnit XML.
pub fn junit_xml(origin: &str, outcomes: &[CheckOutcome]) -> Result<String, CheckError> {
    let mut report = Report::new(format!("magstand check {origin}"));
    for c in outcomes {
        let mut suite = TestSuite::new(c.name.as_str());
        suite.add_properties([
            Property::new("scenario", c.scenario.as_str()),
            Property::new("method", c.method.as_str()),
            Property::new("runs", c.runs.to_string()),
            Property::new("seed", c.seed.to_string()),
        ]);
        for r in &c.results {
            let status = if r.passed {
                TestCaseStatus::success()
            } else {
                let kind = if r.error.is_some() {
                    NonSuccessKind::Error
                } else {
                    NonSuccessKind::Failure
                };
                let mut s = TestCaseStatus::non_success(kind);
                s.set_message(format!("{} = {} is not {}", r.key, r.measured, r.bound));
                s.set_type(if r.error.is_some() {
                    "could not be measured"
                } else {
                    "limit exceeded"
                });
                s.set_description(r.spread.as_str());
                s
            };
            let mut case = TestCase::new(format!("{} {}", r.key, r.bound), status);
            case.set_classname(c.name.as_str());
            case.set_system_out(format!("measured {} ({})", r.measured, r.spread));
            suite.add_test_case(case);
        }
        report.add_test_suite(suite);
    }
    report
        .to_string()
        .map_err(|e| CheckError::Junit(e.to_string()))
}
