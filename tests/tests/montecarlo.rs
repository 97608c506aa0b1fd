//! Monte Carlo studies: efficiency against the Cramer-Rao bound on a scenario whose disturbance
//! has exactly the fixed structure, determinism over thread counts, and shards that merge into
//! the same summary as one machine.
use magstand_study::{Shard, Silent, StudyConfig, StudyResult, Summary, merge, run_study};
use magstand_tests::scenario;

fn tables_study(runs: usize, methods: &[&str]) -> magstand_study::ValidStudy {
    // Shorter dwell than the shipped file, same noise law: enough rows per run for the bound to
    // be tight, quick enough for CI.
    let s = scenario(
        "czyba2015-tables",
        &["program.dwell_s=1.0", "stand.enabled=false"],
    );
    let mut c = StudyConfig::new(runs, 11);
    c.methods = methods.iter().map(|m| m.to_string()).collect();
    c.check(&s).expect("valid study")
}

#[test]
fn weighted_global_estimation_reaches_the_cramer_rao_bound_and_the_others_do_not() {
    let study = tables_study(160, &["global", "global-weighted", "paper-local"]);
    let r = run_study(&study, None, &Silent).unwrap();
    let s = Summary::new(r.info, &r.outcomes);
    let ratio = |m: &str| s.method(m).unwrap().crlb_ratio.unwrap();
    let mse = |m: &str| s.method(m).unwrap().mse_crlb_ratio.unwrap();
    let (w, g) = (ratio("global-weighted"), ratio("global"));
    // 160 runs estimate a variance to about +-11 % per parameter; the trace averages several.
    assert!((0.8..1.25).contains(&w), "weighted efficiency {w}");
    assert!(
        (0.8..1.25).contains(&mse("global-weighted")),
        "weighted mse ratio {}",
        mse("global-weighted")
    );
    assert!(
        g > w * 1.1,
        "unweighted {g} should be clearly above weighted {w}"
    );
    // The paper's local estimation does not aim at the tables' parameters: its error is bias.
    let local = s.method("paper-local").unwrap();
    let bias2: f64 = local.parameters.iter().map(|p| p.bias * p.bias).sum();
    let var: f64 = local.parameters.iter().map(|p| p.sd * p.sd).sum();
    assert!(
        bias2 > var,
        "local estimation: bias^2 {bias2} vs variance {var}"
    );
    // The bound is a bound: no parameter of an unbiased estimator spreads less (within the
    // sampling error of 160 runs, about 6 % on an sd).
    for m in ["global", "global-weighted"] {
        for p in &s.method(m).unwrap().parameters {
            assert!(
                p.sd > 0.8 * p.crlb_sd,
                "{m} {}: sd {} below the bound's {}",
                p.name,
                p.sd,
                p.crlb_sd
            );
        }
    }
}

#[test]
fn results_do_not_depend_on_thread_count_and_shards_merge_to_the_whole() {
    let methods = ["px4", "global-weighted", "automatic"];
    let whole = tables_study(6, &methods);
    let one = run_study(&whole, Some(1), &Silent).unwrap();
    let two = run_study(&whole, Some(2), &Silent).unwrap();
    let bytes = |r: &StudyResult| magstand_study::runs_csv::to_bytes(&r.outcomes).unwrap();
    assert_eq!(
        bytes(&one),
        bytes(&two),
        "runs.csv differs between 1 and 2 threads"
    );

    let dir = tempfile::tempdir().unwrap();
    let mut shard_results = Vec::new();
    for k in 1..=3 {
        let s = scenario(
            "czyba2015-tables",
            &["program.dwell_s=1.0", "stand.enabled=false"],
        );
        let mut c = StudyConfig::new(6, 11);
        c.methods = methods.iter().map(|m| m.to_string()).collect();
        c.shard = Shard { index: k, count: 3 };
        let r = run_study(&c.check(&s).unwrap(), Some(1), &Silent).unwrap();
        let d = dir.path().join(format!("shard{k}"));
        std::fs::create_dir(&d).unwrap();
        assert!(r.write(&d).unwrap().is_none(), "a shard writes no summary");
        shard_results.push(StudyResult::read(&d).unwrap());
    }
    // Given in any order.
    shard_results.reverse();
    let merged = merge(shard_results.clone()).unwrap();
    let whole_summary = Summary::new(one.info.clone(), &one.outcomes).to_json();
    let merged_summary = Summary::new(merged.info.clone(), &merged.outcomes).to_json();
    assert_eq!(whole_summary, merged_summary);

    // A missing shard, a repeated shard, and a shard of another study are refused by name.
    let e = merge(shard_results[..2].to_vec()).unwrap_err().to_string();
    assert!(e.contains("missing"), "{e}");
    let mut twice = shard_results.clone();
    twice.push(shard_results[0].clone());
    let e = merge(twice).unwrap_err().to_string();
    assert!(e.contains("repeats"), "{e}");
    let mut other = shard_results.clone();
    other[0].info.seed += 1;
    let e = merge(other).unwrap_err().to_string();
    assert!(e.contains("another study"), "{e}");
}

#[test]
fn a_corrupted_runs_file_is_refused_with_row_and_column() {
    let study = tables_study(2, &["px4"]);
    let r = run_study(&study, Some(1), &Silent).unwrap();
    let dir = tempfile::tempdir().unwrap();
    r.write(dir.path()).unwrap();
    let path = dir.path().join("runs.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut cells: Vec<String> = lines[2].split(',').map(String::from).collect();
    cells[7] = "NaN".into();
    lines[2] = cells.join(",");
    std::fs::write(&path, lines.join("\n")).unwrap();
    let e = StudyResult::read(dir.path()).unwrap_err().to_string();
    assert!(
        e.contains("row 3") && e.contains("rmse_ut") && e.contains("runs.csv"),
        "{e}"
    );
}
