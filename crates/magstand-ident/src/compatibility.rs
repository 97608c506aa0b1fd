//! The autopilots' own figures beside a model's, on the same data, so that users of either
//! autopilot can compare in the terms they know.
//!
//! * PX4: the R² of PX4's least-squares line (only its slope is kept, as
//!   `CAL_MAGn_{X,Y,Z}COMP`), per axis, and its RMSE on held-out time blocks.
//! * ArduPilot: compassmot's interference percentage, the field change its running-average
//!   line predicts at the top of the recorded range in percent of 530 mG (compassmot's fixed
//!   reference, `AP_ARMING_COMPASS_MAGFIELD_EXPECTED`), with ArduPilot's guidance (below 30 %
//!   fine, 30-60 % a grey zone, above 60 % unacceptable); and the same line's R² and held-out
//!   RMSE.
use crate::IdentError;
use crate::config::{Family, Fit, FitConfig};
use crate::dataset::{Dataset, InputKind};
use crate::model::{FitSummary, Model};
use magstand_core::{Recording, Vec3};

/// The field compassmot divides by for its interference percentage (530 mG), µT.
pub const ARDUPILOT_EXPECTED_FIELD_UT: f64 = 53.0;

/// ArduPilot's interference percentage of a disturbance vector.
pub fn ardupilot_interference_pct(dist_ut: Vec3) -> f64 {
    dist_ut.norm() / ARDUPILOT_EXPECTED_FIELD_UT * 100.0
}

/// One model's figures on the data.
#[derive(Debug, Clone, PartialEq)]
pub struct Figures {
    /// Coefficient of determination on all rows, per axis.
    pub r2: [f64; 3],
    /// RMSE on held-out time blocks of a fit that did not see them, per axis, µT.
    pub holdout_rmse_ut: [f64; 3],
    /// Predicted field change at the top of the recorded input range in percent of 530 mG;
    /// `None` when too few rows stand near the top (see [`Compatibility::withheld`]).
    pub interference_pct: Option<f64>,
}

/// A model beside the PX4 and ArduPilot lines fitted to the same data.
#[derive(Debug, Clone, PartialEq)]
pub struct Compatibility {
    /// The model's own figures.
    pub model: Figures,
    /// PX4's line (slope only).
    pub px4: Figures,
    /// ArduPilot compassmot's running-average line; `None` when too few rows update it for
    /// its figures to mean anything (see [`Compatibility::withheld`]).
    pub ardupilot: Option<Figures>,
    /// Why figures were withheld, in words.
    pub withheld: Vec<String>,
    /// Whether the lines ran on the autopilot's own throttle (the recording's
    /// `autopilot_throttle`) rather than on the model's input.
    pub on_autopilot_throttle: bool,
}

/// Rows that must lie within [`TOP_BAND`] of the top of the recorded input range for a figure
/// at the top to be given: the mean of ten rows has a third of one row's scatter.
pub const MIN_TOP_ROWS: usize = 10;
/// Width of the band below the top of the recorded range, as a fraction of the range.
pub const TOP_BAND: f64 = 0.1;

fn figures(model: &Model, top: Option<f64>) -> Result<Figures, IdentError> {
    let summary: &FitSummary = model.summary.as_ref().ok_or_else(|| IdentError::Data {
        origin: model.method.clone(),
        message: "the model has no fit summary (it was not fitted by magstand fit)".into(),
    })?;
    let mut s = model.scratch();
    Ok(Figures {
        r2: summary.r2,
        holdout_rmse_ut: summary.holdout_rmse_ut,
        interference_pct: top
            .map(|top| ardupilot_interference_pct(model.dist_at_input(top, &mut s))),
    })
}

/// Fits the PX4 and ArduPilot lines on the recording `model` was fitted on and puts their
/// figures beside the model's. A per-motor model's lines are of the overall throttle.
pub fn compatibility(
    model: &Model,
    rec: &Recording,
    origin: &str,
) -> Result<Compatibility, IdentError> {
    let input = match model.input.kind {
        InputKind::Current => InputKind::Current,
        InputKind::Throttle | InputKind::Motors => InputKind::Throttle,
    };
    // The autopilots' throttle lines multiply their own throttle, the thrust demand, where
    // the recording holds it: their thrust curve maps it to the motor commands the model is
    // fitted on, and a line in one is not a line in the other.
    let own_throttle = match input {
        InputKind::Throttle => rec
            .autopilot_throttle(std::path::Path::new(origin))
            .map_err(|e| IdentError::Data {
                origin: origin.into(),
                message: e.to_string(),
            })?,
        _ => None,
    };
    let on_own_throttle = own_throttle.map(|demand| Recording {
        thr: vec![demand],
        overall_only: true,
        ..rec.clone()
    });
    let lines_rec = on_own_throttle.as_ref().unwrap_or(rec);
    // Without motors-off rows (a flight), the model's own reference stands in.
    let data = Dataset::from_recording_or(
        lines_rec,
        input,
        origin,
        Some(Vec3::from(model.reference_ut)),
    )?;
    // The top of the recorded range, in each input's own units (the model's, and the lines'
    // where they run on the autopilot's throttle), where enough rows stand near it; a figure
    // withheld says why.
    let mut withheld = Vec::new();
    let unit = match input {
        InputKind::Current => " A",
        _ => "",
    };
    let mut top_of = |rec: &Recording, what: &str| -> Option<f64> {
        let raw: Vec<f64> = (0..rec.len()).map(|r| data.spec.raw(rec, r)).collect();
        let top = raw.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let bottom = raw.iter().copied().fold(f64::INFINITY, f64::min);
        let near_top = raw
            .iter()
            .filter(|v| **v >= top - TOP_BAND * (top - bottom))
            .count();
        if near_top >= MIN_TOP_ROWS {
            return Some(top);
        }
        withheld.push(format!(
            "interference{what}: only {near_top} rows lie within {:.0} % of the top of the recorded range ({top:.2}{unit}); a figure at the top needs at least {MIN_TOP_ROWS}",
            TOP_BAND * 100.0
        ));
        None
    };
    let top = top_of(rec, "");
    let lines_top = match &on_own_throttle {
        Some(own) if top.is_some() => top_of(own, " of the lines, on the autopilot's own throttle"),
        _ => top,
    };
    let updates = crate::baseline::compassmot_updates(&data, &|_| true);
    let line = |family: Family| -> Result<Figures, IdentError> {
        figures(
            &FitConfig::baseline(family)
                .with_input(input)
                .check()?
                .fit(&data)?,
            lines_top,
        )
    };
    // The two lines are independent fits: one per core.
    let converged = updates >= crate::baseline::COMPASSMOT_CONVERGED_UPDATES;
    let (px4, ardupilot) = rayon::join(
        || line(Family::Px4),
        || converged.then(|| line(Family::ArduPilot)),
    );
    let ardupilot = if let Some(figures) = ardupilot {
        Some(figures?)
    } else {
        withheld.push(format!(
            "compassmot: ArduPilot's running average would update on only {updates} rows (throttle above 0{}); starting from zero it needs {} updates to hold less than 5 % of its start",
            if input == InputKind::Current {
                ", at least 3 A"
            } else {
                ""
            },
            crate::baseline::COMPASSMOT_CONVERGED_UPDATES
        ));
        None
    };
    Ok(Compatibility {
        model: figures(model, top)?,
        px4: px4?,
        ardupilot,
        withheld,
        on_autopilot_throttle: on_own_throttle.is_some(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::local_linear::Estimation;

    /// A 21-level stair whose deviation is `dist(u)` plus a small deterministic ripple.
    fn stair(dist: impl Fn(f64) -> Vec3) -> Recording {
        let mut rec = Recording {
            thr: vec![vec![]],
            overall_only: true,
            ..Default::default()
        };
        for k in 0..4200 {
            let u = ((k / 200) as f64 / 20.0).min(1.0);
            rec.t_s.push(k as f64 * 0.01);
            rec.thr[0].push(u);
            let ripple = 0.05 * ((k as f64) * 1.7).sin();
            rec.mag_ut
                .push(Vec3::new(20.0, 1.0, 45.0) + dist(u) + Vec3::repeat(ripple));
        }
        rec
    }

    #[test]
    fn a_straight_disturbance_gives_the_lines_full_marks_and_compassmots_percentage() {
        let k = Vec3::new(6.0, -8.0, 24.0);
        let rec = stair(|u| k * u);
        let model = FitConfig::paper()
            .check()
            .unwrap()
            .fit_recording(&rec, "line")
            .unwrap();
        let c = compatibility(&model, &rec, "line").unwrap();
        for f in [&c.model, &c.px4] {
            assert!(f.r2.iter().all(|r| *r > 0.99), "{c:?}");
        }
        // |k| at full throttle over 530 mG.
        let want = k.norm() / 53.0 * 100.0;
        assert!(
            (c.px4.interference_pct.unwrap() - want).abs() < 0.5,
            "{c:?} vs {want}"
        );
        assert!(
            (c.model.interference_pct.unwrap() - want).abs() < 0.5,
            "{c:?} vs {want}"
        );
        assert!(c.withheld.is_empty(), "{c:?}");
    }

    #[test]
    fn a_curved_disturbance_is_explained_by_the_model_and_not_by_the_lines() {
        let rec = stair(|u| Vec3::new(2.0, -3.0, 12.0) * (u * u * u * 3.0));
        let model = FitConfig::evenly_spaced(5, Estimation::Global)
            .check()
            .unwrap()
            .fit_recording(&rec, "cubic")
            .unwrap();
        let c = compatibility(&model, &rec, "cubic").unwrap();
        for a in 0..3 {
            assert!(
                c.model.r2[a] > 0.99
                    && c.px4.r2[a] < 0.9
                    && c.ardupilot.as_ref().unwrap().r2[a] < 0.9,
                "axis {a}: {c:?}"
            );
            assert!(
                c.model.holdout_rmse_ut[a] < c.px4.holdout_rmse_ut[a],
                "{c:?}"
            );
        }
    }

    /// The autopilots multiply their line by their own throttle, the thrust demand, which
    /// their thrust curve maps to the motor commands. A disturbance straight in the demand
    /// (here the commands are its square root) is a line for the autopilots where the
    /// recording holds the demand (`autopilot_throttle`), and a curve in the commands where it
    /// does not.
    #[test]
    fn the_lines_run_on_the_autopilots_own_throttle_where_it_is_logged() {
        let k = Vec3::new(6.0, -8.0, 24.0);
        let mut rec = stair(|u| k * (u * u));
        let demand: Vec<f64> = rec.thr[0].iter().map(|u| u * u).collect();
        let model = FitConfig::evenly_spaced(5, Estimation::Global)
            .check()
            .unwrap()
            .fit_recording(&rec, "square")
            .unwrap();
        let without = compatibility(&model, &rec, "square").unwrap();
        rec.extra.push((
            magstand_core::AUTOPILOT_THROTTLE.into(),
            demand.iter().map(|d| format!("{d:.6}")).collect(),
        ));
        let with = compatibility(&model, &rec, "square").unwrap();
        for a in 0..3 {
            assert!(
                with.px4.r2[a] > 0.99 && without.px4.r2[a] < 0.97,
                "axis {a}: with the demand {:?}, without {:?}",
                with.px4,
                without.px4
            );
        }
        // The model's own figures do not depend on the lines' input.
        assert_eq!(with.model, without.model);
        // Both tops have rows enough: |k| at a demand of 1 (commands at 1) over 530 mG.
        let want = k.norm() / 53.0 * 100.0;
        let got = with.px4.interference_pct.expect("a figure at the top");
        assert!((got - want).abs() < 0.5, "{got} against {want}");
        rec.extra[0].1[7] = "1.5".into();
        let e = compatibility(&model, &rec, "square").expect_err("a demand beyond 1");
        assert!(e.to_string().contains("row 8"), "{e}");
    }

    /// Regression: on a log ending in a spin-down, the compassmot emulation gave an R² of
    /// -1384 and 557 % interference: it updated its running average on every row with any
    /// throttle, where ArduPilot's loop needs 3 A for the current form, and it reported
    /// figures that rested on a handful of rows. Figures with too few rows behind them are now
    /// withheld, with the reason.
    #[test]
    fn figures_with_too_few_rows_behind_them_are_withheld_with_the_reason() {
        let k = Vec3::new(6.0, -8.0, 24.0);
        // A short run: motors off for 2 s, a ramp up for 1.5 s (150 rows at 100 Hz), and a
        // single spike to full throttle at the end.
        let mut rec = Recording {
            thr: vec![vec![]],
            overall_only: true,
            ..Default::default()
        };
        for i in 0..352 {
            let u = if i < 200 {
                0.0
            } else if i < 351 {
                0.1 + 0.5 * (i - 200) as f64 / 150.0
            } else {
                1.0
            };
            rec.t_s.push(i as f64 * 0.01);
            rec.thr[0].push(u);
            let ripple = 0.05 * ((i as f64) * 1.7).sin();
            rec.mag_ut
                .push(Vec3::new(20.0, 1.0, 45.0) + k * u + Vec3::repeat(ripple));
        }
        let model = FitConfig::evenly_spaced(3, Estimation::Global)
            .check()
            .unwrap()
            .fit_recording(&rec, "short")
            .unwrap();
        let c = compatibility(&model, &rec, "short").unwrap();
        assert!(c.ardupilot.is_none(), "{c:?}");
        assert!(
            c.model.interference_pct.is_none() && c.px4.interference_pct.is_none(),
            "{c:?}"
        );
        let text = c.withheld.join("; ");
        assert!(
            text.contains("only 1 rows lie within 10 %") && text.contains("only 152 rows"),
            "{text}"
        );
    }

    #[test]
    fn compassmot_in_current_form_updates_only_from_3_amperes() {
        let mut rec = stair(|u| Vec3::new(6.0, -8.0, 24.0) * u);
        // 2 A with the motors just on, 20 A at full throttle.
        rec.bat_a = Some(rec.thr[0].iter().map(|u| 2.0 + 18.0 * u).collect());
        let data = Dataset::from_recording(&rec, InputKind::Current, "amps").unwrap();
        let updates = crate::baseline::compassmot_updates(&data, &|_| true);
        let at_least_3a = rec
            .bat_a
            .as_ref()
            .unwrap()
            .iter()
            .filter(|a| **a >= 3.0)
            .count();
        assert_eq!(updates, at_least_3a);
        assert!(updates < rec.len() - 200, "{updates}");
    }
}
