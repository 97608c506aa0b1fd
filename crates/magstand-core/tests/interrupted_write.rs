//! Regression: a run stopped by SIGINT or SIGTERM while writing left its hidden
//! `.NAME.PID.tmp` files behind for good. The signal handler now calls
//! `remove_pending_temporaries`; this test (alone in its process, so no other writer shares the
//! list) checks that it removes exactly the temporaries still being written and leaves the
//! targets as they were.

use magstand_core::{CoreError, atomic_file};

#[test]
fn pending_temporaries_are_removed_and_targets_left_alone() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("recording.csv");
    std::fs::write(&path, "old").unwrap();
    let staged = atomic_file::stage_with::<CoreError>(&path, |w| {
        w.write_all(b"new, half written")
            .map_err(|e| CoreError::Io {
                path: path.clone(),
                source: e,
            })
    })
    .unwrap();
    let temporaries = || {
        std::fs::read_dir(dir.path())
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
            .count()
    };
    assert_eq!(temporaries(), 1);
    atomic_file::remove_pending_temporaries();
    assert_eq!(temporaries(), 0);
    assert!(
        staged.commit().is_err(),
        "a removed temporary cannot be committed"
    );
    assert_eq!(std::fs::read(&path).unwrap(), b"old");
}
