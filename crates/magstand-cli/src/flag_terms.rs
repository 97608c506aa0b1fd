//! Library messages in the command line's terms. The libraries name a setting by its
//! configuration field between backticks (`max_delay_s`, `mag`); each command puts its own flag
//! in its place, so policy about flags lives here and nowhere else.

/// `text` with every `` `setting` `` of `flags` replaced by `` `--flag` ``.
pub fn in_flag_terms(text: &str, flags: &[(&str, &str)]) -> String {
    let mut out = text.to_string();
    for (setting, flag) in flags {
        out = out.replace(&format!("`{setting}`"), &format!("`{flag}`"));
    }
    out
}

/// The flags of `magstand import`, by the field of `ImportOptions` they set.
pub const IMPORT_FLAGS: [(&str, &str); 5] = [
    ("mag", "--mag"),
    ("motors", "--motors"),
    ("outputs", "--outputs"),
    ("pwm_range", "--pwm-range"),
    ("window_s", "--from-s/--to-s window"),
];

/// The flags of `magstand diagnose`, by the field of `DiagnoseConfig` they set.
pub const DIAGNOSE_FLAGS: [(&str, &str); 2] =
    [("significance", "--significance"), ("block_s", "--block-s")];

/// The flags of `magstand export`.
pub const EXPORT_FLAGS: [(&str, &str); 1] = [("recording", "--recording R.csv")];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_become_flags_and_other_words_stay() {
        assert_eq!(
            in_flag_terms(
                "`mag` = 5: no instance 5; `mag` picks another; a mag field",
                &IMPORT_FLAGS
            ),
            "`--mag` = 5: no instance 5; `--mag` picks another; a mag field"
        );
    }
}
