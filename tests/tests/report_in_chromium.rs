//! The report as a person sees it: rendered by headless Chromium, every figure is present, laid
//! out with a real size, and has drawn content.
//!
//! Chromium (Debian's `chromium` package) is installed by `.ci/run`. Outside CI, when it is
//! missing, the test says so and passes; with `CI=true` a missing Chromium is a failure.
use std::process::Command;

use magstand_ident::{Fit, FitConfig};
use magstand_report::{ReportInputs, build};
use magstand_tests::run;

/// Reports, per figure, the rendered size of its SVG and how many shapes it drew, into an
/// attribute that `--dump-dom` prints after layout.
const PROBE: &str = r#"<script>
window.addEventListener('load', () => {
  const out = [...document.querySelectorAll('figure.figure')].map(f => {
    const svg = f.querySelector('svg');
    const r = svg ? svg.getBoundingClientRect() : {width: 0, height: 0};
    const shapes = svg ? svg.querySelectorAll('path,polyline,polygon,circle,rect,line').length : 0;
    const text = svg ? svg.querySelectorAll('text').length : 0;
    return [f.id, Math.round(r.width), Math.round(r.height), shapes, text].join(':');
  });
  document.body.setAttribute('data-rendered', out.join(' '));
});
</script></body>"#;

fn chromium() -> Option<&'static str> {
    ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|c| {
            Command::new(c)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
}

#[test]
fn every_figure_renders_with_size_and_content() {
    let Some(browser) = chromium() else {
        assert!(
            std::env::var("CI").is_err(),
            "CI=true but no chromium: .ci/run must install Debian's chromium package"
        );
        eprintln!("chromium not installed: skipping the rendering check (CI installs it)");
        return;
    };
    let ident = run(
        "czyba2015-stair",
        &[
            "program.steps=8",
            "program.dwell_s=2.0",
            "stand.enabled=false",
        ],
        3,
    );
    let valid = run(
        "czyba2015-stair",
        &[
            "program.steps=8",
            "program.dwell_s=2.0",
            "program.direction=\"down\"",
            "stand.enabled=false",
        ],
        4,
    );
    let data = magstand_ident::Dataset::from_recording(
        &ident,
        magstand_ident::InputKind::Throttle,
        "ident",
    )
    .unwrap();
    let model = FitConfig::automatic().check().unwrap().fit(&data).unwrap();
    let nominal = magstand_tests::scenario("czyba2015-stair", &["stand.enabled=false"]);
    let diagnosis = magstand_diagnose::diagnose(
        &valid,
        "validation",
        &nominal,
        &magstand_diagnose::DiagnoseConfig::default()
            .check()
            .unwrap(),
    )
    .unwrap();
    let report = build(&ReportInputs {
        recording: &valid,
        recording_name: "validation".into(),
        model: Some(&model),
        physics: None,
        diagnosis: Some(&diagnosis),
        study: None,
        provenance: vec![("test".into(), "report_in_chromium".into())],
    })
    .unwrap();
    let expected: Vec<String> = report
        .sections
        .iter()
        .flat_map(|s| s.figures.iter().map(|f| format!("fig-{}", f.name)))
        .collect();
    assert!(expected.len() >= 15, "figures: {expected:?}");
    let dir = tempfile::tempdir().unwrap();
    report.write(dir.path()).unwrap();
    let page = dir.path().join("probe.html");
    let html = std::fs::read_to_string(dir.path().join("index.html")).unwrap();
    std::fs::write(&page, html.replace("</body>", PROBE)).unwrap();
    let out = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--virtual-time-budget=5000",
            "--dump-dom",
        ])
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("chromium runs");
    let dom = String::from_utf8_lossy(&out.stdout);
    let rendered = dom
        .split("data-rendered=\"")
        .nth(1)
        .and_then(|s| s.split('"').next())
        .unwrap_or_else(|| {
            panic!(
                "no probe output; chromium said: {}",
                String::from_utf8_lossy(&out.stderr)
            )
        });
    let figures: Vec<Vec<&str>> = rendered
        .split(' ')
        .map(|f| f.split(':').collect())
        .collect();
    let ids: Vec<String> = figures.iter().map(|f| f[0].to_string()).collect();
    assert_eq!(ids, expected, "figures on the page");
    for f in &figures {
        let (w, h, shapes, text): (u32, u32, u32, u32) = (
            f[1].parse().unwrap(),
            f[2].parse().unwrap(),
            f[3].parse().unwrap(),
            f[4].parse().unwrap(),
        );
        assert!(w >= 300 && h >= 200, "{}: rendered {w}x{h}", f[0]);
        assert!(
            shapes >= 5 && text >= 4,
            "{}: {shapes} shapes, {text} labels",
            f[0]
        );
    }
}
