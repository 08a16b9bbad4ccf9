//! End-to-end test support for mrtwin (see `tests/`).
//!
//! The tests of the `mrtwin` binary itself live in `cli/tests/`: only a binary's own
//! package gets it built before its integration tests and its path as
//! `CARGO_BIN_EXE_mrtwin`, so tests here could not find it reliably. They use this
//! library (a dev-dependency of `cli`) for the Python interop peers.

use std::path::PathBuf;

/// The repository root.
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// The Python of the interop venv: `$MRTWIN_PYTHON`, else `<repo>/.venv/bin/python`.
///
/// Panics with what to do when it is missing: `scripts/test-all.sh` creates it with
/// `scripts/setup-venv.sh` (rclpy + Fast DDS, eclipse-zenoh, rosbags, mcap from PyPI).
pub fn python() -> PathBuf {
    let p = std::env::var_os("MRTWIN_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo_root().join(".venv/bin/python"));
    assert!(
        p.exists(),
        "interop Python {} not found: run `bash scripts/setup-venv.sh` (scripts/test-all.sh does)",
        p.display()
    );
    p
}

/// Run `python -c SCRIPT args…` with a time limit; returns stdout, panics with stderr on
/// failure or timeout.
pub fn run_python(script: &str, args: &[&str], timeout: std::time::Duration) -> String {
    use std::io::Read;
    use std::process::{Command, Stdio};
    let mut child = Command::new(python())
        .arg("-c")
        .arg(script)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start python");
    let deadline = std::time::Instant::now() + timeout;
    loop {
        if let Some(status) = child.try_wait().expect("wait python") {
            let mut out = String::new();
            let mut err = String::new();
            child.stdout.take().unwrap().read_to_string(&mut out).ok();
            child.stderr.take().unwrap().read_to_string(&mut err).ok();
            assert!(status.success(), "python failed ({status}):\n{err}\n{out}");
            return out;
        }
        if std::time::Instant::now() > deadline {
            child.kill().ok();
            let mut err = String::new();
            child.stderr.take().unwrap().read_to_string(&mut err).ok();
            panic!("python did not finish within {timeout:?}:\n{err}");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}
