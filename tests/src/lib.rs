//! End-to-end test support for mrtwin (see `tests/`).
//!
//! The tests of the `mrtwin` binary itself live in `cli/tests/`: only a binary's own
//! package gets it built before its integration tests and its path as
//! `CARGO_BIN_EXE_mrtwin`, so tests here could not find it reliably. They use this
//! library (a dev-dependency of `cli`) for the Python interop peers.
//!
//! [`fuzz`] holds the fuzz generators and the campaign runner of every parser, shared by
//! the driver `src/bin/fuzz-parsers.rs` and the fast slice `tests/fuzz_parsers.rs`.

pub mod fuzz;

use std::path::{Path, PathBuf};
use std::process::Output;

/// Run the binary at `bin` (a test's `env!("CARGO_BIN_EXE_…")`) with `args`, to its end.
pub fn run<S: AsRef<std::ffi::OsStr>>(bin: &str, args: &[S]) -> Output {
    std::process::Command::new(bin)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {bin}: {e}"))
}

/// `o`, once it is known to have succeeded; else a panic with `what` and its stdout and
/// stderr.
pub fn succeeded(o: Output, what: &str) -> Output {
    assert!(
        o.status.success(),
        "{what} failed:\n{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// Column `name` of a CSV file with a header row, as numbers (NaN included).
pub fn csv_column(path: &Path, name: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let k = header.iter().position(|h| *h == name).unwrap();
    lines
        .map(|l| l.split(',').nth(k).unwrap().parse::<f64>().unwrap())
        .collect()
}

/// A JSON file (a `--json` report), parsed; a panic naming the file otherwise.
pub fn read_json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The entry of parameter `key` in the `parameters` of a `mrtwin fit --json` report
/// (`key`, `start`, `value`, `std_error`, `ci95`), if the fit moved it.
pub fn fitted_parameter<'a>(
    report: &'a serde_json::Value,
    key: &str,
) -> Option<&'a serde_json::Value> {
    report["parameters"]
        .as_array()?
        .iter()
        .find(|q| q["key"] == key)
}

/// RMS of the finite values of `x`.
pub fn rms_finite(x: &[f64]) -> f64 {
    let v: Vec<f64> = x.iter().copied().filter(|e| e.is_finite()).collect();
    (v.iter().map(|e| e * e).sum::<f64>() / v.len() as f64).sqrt()
}

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
    set_up_file(
        "MRTWIN_PYTHON",
        ".venv/bin/python",
        "interop Python",
        "scripts/setup-venv.sh",
    )
}

/// A file a set-up script makes: `$var`, else `<repo>/default`. Panics naming the script
/// to run when it is missing (`scripts/test-all.sh` runs them all).
fn set_up_file(var: &str, default: &str, what: &str, script: &str) -> PathBuf {
    let p = std::env::var_os(var)
        .map(PathBuf::from)
        .unwrap_or_else(|| repo_root().join(default));
    assert!(
        p.is_file(),
        "{what} {} not found: run `bash {script}` (scripts/test-all.sh does)",
        p.display()
    );
    p
}

/// Run `python -c SCRIPT args…` with a time limit; returns stdout, panics with stderr on
/// failure or timeout. Output is drained while the script runs, so a chatty script never
/// blocks on a full pipe.
pub fn run_python(script: &str, args: &[&str], timeout: std::time::Duration) -> String {
    run_python_env(script, args, &[], timeout)
}

/// [`run_python`] with extra environment variables (e.g. `ROS_DOMAIN_ID`).
pub fn run_python_env(
    script: &str,
    args: &[&str],
    env: &[(&str, &str)],
    timeout: std::time::Duration,
) -> String {
    let mut cmd = std::process::Command::new(python());
    cmd.arg("-c")
        .arg(script)
        .args(args)
        .envs(env.iter().copied());
    run_bounded(cmd, "python", timeout)
}

/// Runs a Python script file with arguments (through `python -c`, so the interop venv's
/// time limit and output draining apply): `run_python(RUN_FILE, &[file, args…], …)`.
pub const RUN_FILE: &str =
    "import runpy, sys; sys.argv = sys.argv[1:]; runpy.run_path(sys.argv[0], run_name='__main__')";

/// Generates proving-ground scenario `seed` (or, with `null_twin`, the same damper,
/// excitation and measurement with nothing hidden) into `dir` with the independent Python
/// simulator (`scripts/proving_ground/generate.py`): the recording's and its meta JSON's
/// paths.
pub fn generate_scenario(dir: &TempDir, seed: u32, null_twin: bool) -> (PathBuf, PathBuf) {
    let generate = repo_root().join("scripts/proving_ground/generate.py");
    let (csv, meta) = (dir.path("r.csv"), dir.path("r.meta.json"));
    let seed_arg = seed.to_string();
    let mut args = vec![
        generate.to_str().unwrap(),
        "--seed",
        &seed_arg,
        "--out",
        csv.to_str().unwrap(),
        "--meta",
        meta.to_str().unwrap(),
    ];
    if null_twin {
        args.push("--null-twin");
    }
    run_python(RUN_FILE, &args, std::time::Duration::from_secs(300));
    (csv, meta)
}

/// The entry of `effect` in a list of entries keyed by `"effect"` (a diagnosis's
/// `findings`, a scenario's `effects`).
pub fn entry_of<'a>(list: &'a serde_json::Value, effect: &str) -> &'a serde_json::Value {
    list.as_array()
        .unwrap()
        .iter()
        .find(|f| f["effect"] == effect)
        .unwrap_or_else(|| panic!("no {effect} in {list}"))
}

/// The environment script of the natively built `mrtwin_msgs` (`scripts/setup-msgs.sh`):
/// `$MRTWIN_MSGS_ENV`, else `<repo>/.msgs/env.sh`.
pub fn msgs_env() -> PathBuf {
    set_up_file(
        "MRTWIN_MSGS_ENV",
        ".msgs/env.sh",
        "the environment of mrtwin_msgs built with rosidl,",
        "scripts/setup-msgs.sh",
    )
}

/// Runs a Python script in the environment of [`msgs_env`] (its venv's Python, which
/// imports `mrtwin_msgs`), with arguments and extra environment; its stdout.
pub fn run_python_with_msgs(
    script: &str,
    args: &[&str],
    env: &[(&str, &str)],
    timeout: std::time::Duration,
) -> String {
    let mut cmd = std::process::Command::new("bash");
    cmd.arg("-c")
        .arg(". \"$0\" && exec python -c \"$1\" \"${@:2}\"")
        .arg(msgs_env())
        .arg(script)
        .args(args)
        .envs(env.iter().copied());
    run_bounded(cmd, "python (mrtwin_msgs)", timeout)
}

/// Runs `cmd` to completion within `timeout` (killed and a panic after it), draining its
/// output; its stdout. Panics with stderr when it fails.
fn run_bounded(mut cmd: std::process::Command, what: &str, timeout: std::time::Duration) -> String {
    use std::io::Read;
    use std::process::Stdio;
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("start {what}: {e}"));
    let mut so = child.stdout.take().expect("stdout");
    let mut se = child.stderr.take().expect("stderr");
    let out = std::thread::spawn(move || {
        let mut s = String::new();
        so.read_to_string(&mut s).ok();
        s
    });
    let err = std::thread::spawn(move || {
        let mut s = String::new();
        se.read_to_string(&mut s).ok();
        s
    });
    let deadline = std::time::Instant::now() + timeout;
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait") {
            break status;
        }
        if std::time::Instant::now() > deadline {
            child.kill().ok();
            child.wait().ok();
            let err = err.join().unwrap_or_default();
            panic!("{what} did not finish within {timeout:?}:\n{err}");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    let out = out.join().unwrap_or_default();
    let err = err.join().unwrap_or_default();
    assert!(status.success(), "{what} failed ({status}):\n{err}\n{out}");
    out
}

/// A scratch directory under the target dir, removed on drop.
pub struct TempDir(PathBuf);

impl TempDir {
    /// A fresh, empty directory named after the test.
    pub fn new(test: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("mrtwin-{test}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("create temp dir");
        Self(dir)
    }

    /// A path inside it.
    pub fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A free loopback TCP port (for a test's own zenoh endpoint).
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("bind a loopback port")
        .port()
}

/// Read `lines` until `pick` maps one to `Some`, at most `timeout`: that value and every
/// line read. Panics with the lines read when the time passes or the stream ends first.
pub fn await_line<T>(
    lines: &std::sync::mpsc::Receiver<String>,
    timeout: std::time::Duration,
    what: &str,
    mut pick: impl FnMut(&str) -> Option<T>,
) -> (T, Vec<String>) {
    let deadline = std::time::Instant::now() + timeout;
    let mut seen = Vec::new();
    loop {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        match lines.recv_timeout(left) {
            Ok(line) => {
                let found = pick(&line);
                seen.push(line);
                if let Some(v) = found {
                    return (v, seen);
                }
            }
            Err(e) => panic!(
                "no {what} within {timeout:?} ({e}); printed:\n{}",
                seen.join("\n")
            ),
        }
    }
}

/// A child process that is killed when the guard drops (a failing test leaves nothing
/// running).
pub struct ChildGuard(pub Option<std::process::Child>);

impl ChildGuard {
    /// Start `cmd` with its stdout and stderr captured.
    pub fn spawn(cmd: &mut std::process::Command) -> Self {
        use std::process::Stdio;
        Self(Some(
            cmd.stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .expect("start child"),
        ))
    }

    /// Wait at most `timeout` for the child to exit; returns (success, stdout, stderr).
    /// Kills it and panics on timeout.
    pub fn wait(mut self, timeout: std::time::Duration) -> (bool, String, String) {
        use std::io::Read;
        let mut child = self.0.take().expect("child present");
        let deadline = std::time::Instant::now() + timeout;
        let status = loop {
            if let Some(s) = child.try_wait().expect("wait child") {
                break s;
            }
            if std::time::Instant::now() > deadline {
                child.kill().ok();
                let mut err = String::new();
                if let Some(mut e) = child.stderr.take() {
                    e.read_to_string(&mut err).ok();
                }
                panic!("child did not exit within {timeout:?}; stderr:\n{err}");
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        };
        let mut out = String::new();
        let mut err = String::new();
        if let Some(mut o) = child.stdout.take() {
            o.read_to_string(&mut out).ok();
        }
        if let Some(mut e) = child.stderr.take() {
            e.read_to_string(&mut err).ok();
        }
        (status.success(), out, err)
    }

    /// The child's stdout line by line on a channel (a thread reads it until it closes).
    pub fn stdout_lines(&mut self) -> std::sync::mpsc::Receiver<String> {
        use std::io::{BufRead, BufReader};
        let stdout = self
            .0
            .as_mut()
            .and_then(|c| c.stdout.take())
            .expect("the child's stdout, not taken before");
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        rx
    }

    /// Send SIGINT (Ctrl-C).
    pub fn interrupt(&self) {
        if let Some(c) = &self.0 {
            let _ = std::process::Command::new("kill")
                .args(["-INT", &c.id().to_string()])
                .status();
        }
    }
}

impl Drop for ChildGuard {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}
