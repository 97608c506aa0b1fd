//! The named methods that comparisons run side by side: the autopilots' straight lines, the
//! paper's model, and magstand's improvements. The demo, the Monte Carlo studies and the report
//! all use this one list, so their tables line up.
use crate::{Estimation, Family, FitConfig, InputKind};

/// How a method fits.
#[derive(Debug, Clone, PartialEq)]
pub enum Fitter {
    /// One fit with these settings.
    Config(FitConfig),
    /// The stand's physics, calibrated (`magstand fit --method physics`); fitted by the
    /// diagnosis crate, which the callers that run it depend on.
    Physics,
    /// The automatic choice among the model families (`magstand fit` with no options).
    Chosen,
}

/// A method with a short id (for files and flags) and a label (for tables).
#[derive(Debug, Clone)]
pub struct Method {
    /// Short id, used in `runs.csv`, SUMMARY.json and `--methods`.
    pub id: &'static str,
    /// Human-readable label.
    pub label: &'static str,
    /// The fit settings of a single-configuration method (every method of [`catalog`]).
    pub config: FitConfig,
    /// How it fits: [`Fitter::Config`] of `config` for the catalog's methods.
    pub fitter: Fitter,
    /// Whether this is the paper's fixed 3-RBF structure (centres 0, 0.5, 1, width 4), whose
    /// parameters a Cramer-Rao bound can be compared against.
    pub fixed_structure: bool,
}

fn paper_structure(estimation: Estimation) -> FitConfig {
    FitConfig::fixed(vec![0.0, 0.5, 1.0], 4.0, estimation)
}

/// Every named method, in the order tables print them.
pub fn catalog() -> Vec<Method> {
    let m = |id, label, config: FitConfig, fixed_structure| Method {
        id,
        label,
        fitter: Fitter::Config(config.clone()),
        config,
        fixed_structure,
    };
    vec![
        m(
            "ardupilot",
            "ArduPilot compassmot (line, running avg)",
            FitConfig::baseline(Family::ArduPilot),
            false,
        ),
        m(
            "px4",
            "PX4 (least-squares line)",
            FitConfig::baseline(Family::Px4),
            false,
        ),
        m("cubic", "cubic", FitConfig::baseline(Family::Cubic), false),
        m(
            "paper-local",
            "paper: 3 RBF, local estimation",
            FitConfig::paper(),
            true,
        ),
        m(
            "global",
            "3 RBF, global estimation",
            paper_structure(Estimation::Global),
            true,
        ),
        m(
            "global-weighted",
            "3 RBF, global, inverse-variance",
            paper_structure(Estimation::Global).with_weighting(true),
            true,
        ),
        m(
            "automatic",
            "magstand: automatic structure",
            FitConfig::automatic(),
            false,
        ),
        m(
            "automatic-current",
            "magstand: automatic, current input",
            FitConfig::automatic().with_input(InputKind::Current),
            false,
        ),
    ]
}

/// Id of the stand's physics method.
pub const PHYSICS_ID: &str = "physics";
/// Id of the automatic choice among model families.
pub const CHOSEN_ID: &str = "chosen";

/// The methods beyond the single-configuration catalog, which a study runs only when asked
/// (`--methods physics,chosen`): the stand's physics, and the automatic choice of `magstand
/// fit`. Their `config` is the local linear family the choice always includes; only
/// `fitter` says how they fit.
pub fn extended() -> Vec<Method> {
    vec![
        Method {
            id: PHYSICS_ID,
            label: "magstand: stand physics, calibrated",
            config: FitConfig::automatic(),
            fitter: Fitter::Physics,
            fixed_structure: false,
        },
        Method {
            id: CHOSEN_ID,
            label: "magstand fit default: family chosen",
            config: FitConfig::automatic(),
            fitter: Fitter::Chosen,
            fixed_structure: false,
        },
    ]
}

/// The id of the local linear family `magstand fit` always tries: the automatic structure on
/// the overall throttle. (With no options `fit` chooses among families: [`CHOSEN_ID`].)
pub const DEFAULT_ID: &str = "automatic";

/// The ids of every named method, comma-separated (for error messages and help).
pub fn ids() -> String {
    catalog()
        .iter()
        .chain(&extended())
        .map(|m| m.id)
        .collect::<Vec<_>>()
        .join(", ")
}

/// The method with this id.
pub fn by_id(id: &str) -> Option<Method> {
    catalog().into_iter().chain(extended()).find(|m| m.id == id)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_unique_and_every_config_checks() {
        let all = catalog();
        for (i, m) in all.iter().enumerate() {
            assert!(
                all[..i].iter().all(|o| o.id != m.id),
                "duplicate id {}",
                m.id
            );
            assert!(m.config.clone().check().is_ok(), "{} does not check", m.id);
            assert_eq!(m.fitter, Fitter::Config(m.config.clone()), "{}", m.id);
            assert_eq!(by_id(m.id).unwrap().label, m.label);
        }
        assert!(by_id("nonsense").is_none());
    }
}
