//! `magstand montecarlo`: accuracy studies against the Cramer-Rao bound, sharding and merging,
//! and the procedure sweep.
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};

use crate::files;
use crate::progress::RunsBar;
use crate::simulate_cmd::load_scenario;
use magstand_study::{
    FigureId, SWEEP_FILE, Shard, StudyConfig, StudyError, StudyResult, Summary, ValidSweep,
    format_figure, run_study, sweep_csv, sweep_rows, write_summary,
};

/// Arguments of `magstand montecarlo`.
#[derive(Args)]
#[command(allow_negative_numbers = true)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct MonteCarloArgs {
    #[command(subcommand)]
    command: Option<MonteCarloCommand>,
    #[command(flatten)]
    study: StudyArgs,
}

#[derive(Subcommand)]
enum MonteCarloCommand {
    /// Merge the shards of one study (their output folders) into the whole study's files.
    Merge(MergeArgs),
}

#[derive(Args)]
#[command(allow_negative_numbers = true)]
struct StudyArgs {
    /// Scenario file, or `builtin:NAME`. Its `[study]` table sets the validation series and
    /// the parameters drawn per run.
    #[arg(long, required = true)]
    scenario: Option<String>,
    /// Runs in the whole study (over all shards).
    #[arg(long, required = true)]
    runs: Option<usize>,
    /// Output folder: runs.csv, study.json, SUMMARY.json (whole studies).
    #[arg(long, required = true)]
    out: Option<PathBuf>,
    /// Also write the summary here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Study seed (default: the scenario's).
    #[arg(long)]
    seed: Option<u64>,
    /// Worker threads (default: all cores; 1 to 1024). Results do not depend on it.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    threads: Option<u16>,
    /// Run only slice K of M (e.g. 3/10); merge the slices with `magstand montecarlo merge`.
    #[arg(long)]
    shard: Option<String>,
    /// Methods to compare, comma-separated ids (default: all the scenario can feed).
    #[arg(long, value_delimiter = ',')]
    methods: Vec<String>,
    /// Override a scenario value for both series, `key=value` (repeatable).
    #[arg(long = "set")]
    overrides: Vec<String>,
    /// Override a value of the identification series only (a procedure setting), `key=value`.
    #[arg(long = "ident-set")]
    ident_overrides: Vec<String>,
    /// Vary one procedure setting of the identification series over values and tabulate the
    /// accuracy against it: `key=v1,v2,...` (e.g. `program.dwell_s=2,5,10`).
    #[arg(long)]
    sweep: Option<String>,
}

#[derive(Args)]
#[command(allow_negative_numbers = true)]
struct MergeArgs {
    /// Shard output folders.
    #[arg(required = true)]
    shards: Vec<PathBuf>,
    /// Output folder for the merged study.
    #[arg(long)]
    out: PathBuf,
    /// Also write the summary here.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// Runs `magstand montecarlo`.
pub fn run(a: MonteCarloArgs) -> Result<()> {
    match a.command {
        Some(MonteCarloCommand::Merge(m)) => merge(m),
        None => study(a.study),
    }
}

fn study(a: StudyArgs) -> Result<()> {
    let (Some(spec), Some(runs), Some(out)) = (a.scenario.clone(), a.runs, a.out.clone()) else {
        bail!("--scenario, --runs and --out are required");
    };
    let scenario = load_scenario(&spec, &a.overrides)?;
    let shard = a
        .shard
        .as_deref()
        .map(|t| Shard::parse(t).map_err(flagged))
        .transpose()?
        .unwrap_or(Shard::ALL);
    let config = |ident: Vec<String>| StudyConfig {
        runs,
        seed: a.seed.unwrap_or(scenario.params().seed),
        methods: a.methods.clone(),
        shard,
        identification_overrides: ident,
    };
    let inputs = files::scenario_inputs(&spec, &scenario);
    let Some(sweep) = &a.sweep else {
        let valid = config(a.ident_overrides.clone())
            .check(&scenario)
            .map_err(flagged)?;
        let methods: Vec<&str> = valid.methods().iter().map(|m| m.id).collect();
        let outputs = study_outputs(&out, &methods, a.json.as_deref());
        files::refuse_overwriting_inputs(&inputs, &outputs)?;
        files::ensure_dir(&out)?;
        let bar = RunsBar::new("montecarlo", valid.run_indices().len());
        let result = run_study(&valid, a.threads.map(usize::from), &bar).map_err(flagged)?;
        drop(bar);
        return finish(&result, &out, a.json.as_deref());
    };

    if let Some(j) = &a.json {
        bail!(
            "--json {} with --sweep: a sweep writes one SUMMARY.json per value, in the value's folder, and its table to sweep.csv; leave --json out",
            j.display()
        );
    }
    if shard != Shard::ALL {
        bail!(
            "--sweep runs whole studies; to spread a sweep over machines, run one sharded study per value with --ident-set KEY=VALUE"
        );
    }
    let sweep = ValidSweep::new(sweep, &scenario, config, &a.ident_overrides).map_err(flagged)?;
    let key = &sweep.key;
    let mut outputs = vec![out.join(SWEEP_FILE)];
    for (folder, valid) in sweep.folders.iter().zip(&sweep.studies) {
        let methods: Vec<&str> = valid.methods().iter().map(|m| m.id).collect();
        outputs.extend(study_outputs(&out.join(folder), &methods, None));
    }
    files::refuse_overwriting_inputs(&inputs, &outputs)?;
    files::ensure_dir(&out)?;
    let mut table = Vec::new();
    for ((v, valid), folder) in sweep.values.iter().zip(&sweep.studies).zip(&sweep.folders) {
        let dir = out.join(folder);
        files::ensure_dir(&dir)?;
        let bar = RunsBar::new(&format!("{key}={v}"), valid.run_indices().len());
        let result = run_study(valid, a.threads.map(usize::from), &bar).map_err(flagged)?;
        drop(bar);
        let summary = result.write(&dir)?.expect("a sweep runs whole studies");
        write_figures(&summary, &result, &dir)?;
        table.push((v.to_string(), summary));
    }
    let text = sweep_csv(key, &table);
    magstand_core::atomic_file::write_bytes(&out.join(SWEEP_FILE), text.as_bytes())?;
    println!("Accuracy against {key} (validation series, {runs} runs per value):\n");
    print!("{}", sweep_pretty(key, &table));
    println!(
        "\nwrote {} and one folder per value",
        out.join(SWEEP_FILE).display()
    );
    Ok(())
}

/// A study error as the command line says it: a study setting by its flag.
fn flagged(e: StudyError) -> anyhow::Error {
    match e {
        StudyError::InvalidSetting {
            setting,
            value,
            expected,
        } => anyhow::anyhow!("--{setting} {value} is not allowed: expected {expected}"),
        e => e.into(),
    }
}

/// Every file a study writes into `out` (and `json`), for the check against its inputs.
fn study_outputs(out: &Path, methods: &[&str], json: Option<&Path>) -> Vec<PathBuf> {
    let mut outputs = StudyResult::files_written(out).to_vec();
    outputs.push(out.join(ERROR_FIGURE));
    outputs.extend(methods.iter().map(|m| out.join(parameter_figure(m))));
    outputs.extend(json.map(Path::to_path_buf));
    outputs
}

const ERROR_FIGURE: &str = "error-vs-throttle.svg";

fn parameter_figure(method: &str) -> String {
    format!("parameter-errors-{method}.svg")
}

fn merge(m: MergeArgs) -> Result<()> {
    let shards = m
        .shards
        .iter()
        .map(|d| StudyResult::read(d).with_context(|| format!("shard {}", d.display())))
        .collect::<Result<Vec<_>>>()?;
    let inputs: Vec<PathBuf> = m
        .shards
        .iter()
        .flat_map(|d| StudyResult::files_read(d))
        .collect();
    let methods: Vec<&str> = shards
        .first()
        .map(|s| s.info.methods.iter().map(String::as_str).collect())
        .unwrap_or_default();
    files::refuse_overwriting_inputs(&inputs, &study_outputs(&m.out, &methods, m.json.as_deref()))?;
    let merged = magstand_study::merge(shards)?;
    files::ensure_dir(&m.out)?;
    finish(&merged, &m.out, m.json.as_deref())
}

/// Writes a result and prints its table (whole studies) or where the shard went.
fn finish(result: &StudyResult, out: &Path, json: Option<&Path>) -> Result<()> {
    match result.write(out)? {
        Some(summary) => {
            if let Some(j) = json {
                write_summary(&summary, j)?;
            }
            let figures = write_figures(&summary, result, out)?;
            print!("{}", summary_table(&summary));
            println!(
                "\nwrote {}, {} and {} figures ({})",
                out.join(magstand_study::RUNS_FILE).display(),
                out.join(magstand_study::SUMMARY_FILE).display(),
                figures.len(),
                figures.join(", ")
            );
        }
        None => {
            let [k, m] = result.info.shard;
            println!(
                "shard {k}/{m} (runs {}..{}) written to {}; merge all shards with `magstand montecarlo merge DIR1 DIR2 ... --out DIR`",
                result.info.run_range[0],
                result.info.run_range[1],
                out.display()
            );
        }
    }
    Ok(())
}

/// Writes the study's figures as SVG files next to its tables; returns their file names.
pub fn write_figures(summary: &Summary, result: &StudyResult, out: &Path) -> Result<Vec<String>> {
    let mut figures = vec![(
        ERROR_FIGURE.to_string(),
        magstand_report::montecarlo::error_against_throttle(summary)?,
    )];
    for m in &summary.methods {
        if !m.parameters.is_empty() {
            figures.push((
                parameter_figure(&m.method),
                magstand_report::montecarlo::parameter_errors(
                    summary,
                    &result.outcomes,
                    &m.method,
                )?,
            ));
        }
    }
    for (name, svg) in &figures {
        magstand_core::atomic_file::write_bytes(&out.join(name), svg.as_bytes())?;
    }
    Ok(figures.into_iter().map(|(n, _)| n).collect())
}

/// The summary as a fixed-width table.
pub fn summary_table(s: &Summary) -> String {
    let mut out = format!(
        "{} runs of {} (seed {}); figures on the validation series against the simulator's truth\n\n",
        s.study.runs, s.study.scenario, s.study.seed
    );
    // As wide as the longest method's label, so the figures stay in their columns.
    let w = s
        .methods
        .iter()
        .map(|m| m.label.chars().count())
        .fold(40, usize::max);
    out += &format!(
        "{:<w$} {:>24} {:>22} {:>10} {:>10} {:>6}\n",
        "method",
        "dist_rmse_ut p50 [p5,p95]",
        "heading_after_deg p50",
        "crlb_ratio",
        "mse_ratio",
        "failed"
    );
    for m in &s.methods {
        let r = m.figure(FigureId::RmseUt);
        let h = m.figure(FigureId::HeadingAfterDeg);
        out += &format!(
            "{:<w$} {:>24} {:>22} {:>10} {:>10} {:>6}\n",
            m.label,
            r.map(|r| format!("{:.3} [{:.3},{:.3}]", r.p50, r.p5, r.p95))
                .unwrap_or_else(|| "-".into()),
            format_figure(h.map(|h| h.p50), 2),
            format_figure(m.crlb_ratio, 2),
            format_figure(m.mse_crlb_ratio, 2),
            m.failures
        );
    }
    out
}

fn sweep_pretty(key: &str, table: &[(String, Summary)]) -> String {
    let mut out = format!(
        "{key:>16} {:<20} {:>12} {:>12} {:>12} {:>10}\n",
        "method", "rmse_ut p50", "rmse_ut p95", "heading p50", "crlb_ratio"
    );
    for r in sweep_rows(table) {
        out += &format!(
            "{:>16} {:<20} {:>12} {:>12} {:>12} {:>10}\n",
            r[0], r[1], r[2], r[3], r[4], r[5]
        );
    }
    out
}
