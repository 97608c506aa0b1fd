/// A setting of the identification, as errors and warnings name it: by what it is in the
/// library's configuration ([`crate::FitConfig`], [`crate::flight::FlightConfig`]), so that a
/// command line can say it in its own terms (its flags).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FitSetting {
    /// Number of local models of a fixed structure.
    LocalModels,
    /// Their centres.
    Centers,
    /// Their widths.
    Widths,
    /// Most local models of the automatic structure.
    MaxModels,
    /// Knots of the noise model.
    SdKnots,
    /// The input the disturbance follows.
    Input,
    /// The Earth field of a flight.
    Earth,
    /// Largest magnetometer delay searched in a flight.
    MaxDelayS,
    /// Largest tilt kept in a flight.
    MaxTiltDeg,
    /// Forgetting factor of the recursive estimation.
    Forgetting,
}

impl FitSetting {
    /// Every setting.
    pub const ALL: [FitSetting; 10] = [
        FitSetting::LocalModels,
        FitSetting::Centers,
        FitSetting::Widths,
        FitSetting::MaxModels,
        FitSetting::SdKnots,
        FitSetting::Input,
        FitSetting::Earth,
        FitSetting::MaxDelayS,
        FitSetting::MaxTiltDeg,
        FitSetting::Forgetting,
    ];

    /// The name messages use, as written between backticks in them.
    pub fn name(self) -> &'static str {
        match self {
            FitSetting::LocalModels => "local_models",
            FitSetting::Centers => "centers",
            FitSetting::Widths => "widths",
            FitSetting::MaxModels => "max_models",
            FitSetting::SdKnots => "sd_knots",
            FitSetting::Input => "input",
            FitSetting::Earth => "earth",
            FitSetting::MaxDelayS => "max_delay_s",
            FitSetting::MaxTiltDeg => "max_tilt_deg",
            FitSetting::Forgetting => "forgetting",
        }
    }
}

impl std::fmt::Display for FitSetting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Everything that can go wrong while identifying or applying a model.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IdentError {
    /// A hyper-parameter is outside its allowed range.
    #[error("invalid setting `{setting}` = {value}: expected {expected}")]
    InvalidSetting {
        /// The setting.
        setting: FitSetting,
        /// Value given.
        value: String,
        /// Allowed range.
        expected: String,
    },
    /// The recording lacks what the fit needs.
    #[error("{origin}: {message}")]
    Data {
        /// File or description of the recording.
        origin: String,
        /// What is missing or wrong.
        message: String,
    },
    /// The data cannot determine the model (e.g. the throttle never varies).
    #[error("{origin}: the data cannot determine the {what}: {why}")]
    Singular {
        /// File or description of the recording.
        origin: String,
        /// Which fit.
        what: String,
        /// Why, in terms of the data.
        why: String,
    },
    /// A model file is malformed or of an unknown version.
    #[error("{origin}: {message}")]
    ModelFile {
        /// File name.
        origin: String,
        /// What is wrong.
        message: String,
    },
    /// Reading or writing a file failed.
    #[error(transparent)]
    Core(#[from] magstand_core::CoreError),
}
