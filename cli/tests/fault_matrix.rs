//! The fault matrix of the live system (issue 15, "Reliability in figures").
//!
//! stand → twin → recorder over zenoh, the twin also serving its iceoryx2 control service
//! to a controller process, all real processes. One fault at a time:
//!
//! 1. kill -9 of the stand, restarted;
//! 2. the stand silent (SIGSTOP for 3 s, then SIGCONT);
//! 3. a burst of duplicated and out-of-order samples (the stand's fault injection);
//! 4. kill -9 of the twin, restarted mid-stream (a late joiner);
//! 5. kill -9 of the controller, restarted;
//! 6. kill -9 of the recorder, restarted;
//! 7. a recorder whose disk fills up (a file-size limit, `RLIMIT_FSIZE`);
//!
//! and last a clean stop of everything. Each row checks what the issue expects: the twin
//! keeps running, its `sensor stream` health shows the fault and recovers to OK; a killed
//! recorder's bag reads back every message of its last flush, a recorder past its file
//! size stops with a message naming the file and the cause; the iceoryx2 resources of a
//! killed process are cleaned up, so its successor connects (the control service admits
//! one client and one server only, so a dead one left in place would lock it out).
//!
//! The health is watched live: this test's own zenoh session is the one every process
//! connects to, and it subscribes to the twin's `/diagnostics`. The table of the rows is
//! printed (to stderr, past the test harness's capture) before the test fails on any row.
//! Own port, damper name, iceoryx2 service prefix; every wait is bounded.
#![cfg(all(feature = "zenoh", feature = "iceoryx2"))]

use std::collections::BTreeMap;
use std::fs::File;
use std::io::Write;
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use bridge::bag::{read_bag, BagContents};
use bridge::iceoryx2::{ControlClient, Iceoryx2Config};
use bridge::transport::{Message, Topic};
use mrtwin_tests::{free_port, TempDir};
use msgs::shm::{ShmRequest, ShmSample};
use msgs::DiagnosticStatus;

/// The environment variable that turns [`fault_matrix_controller_process`] into the
/// controller (its value: the iceoryx2 configuration as JSON).
const CONTROLLER_ENV: &str = "MRTWIN_FAULT_MATRIX_CONTROLLER";
/// The controller's stop file: once it exists, the controller ends its loop and exits.
const CONTROLLER_STOP_ENV: &str = "MRTWIN_FAULT_MATRIX_CONTROLLER_STOP";
/// Longest wait for the health to show a fault.
const SHOW_WITHIN: Duration = Duration::from_secs(10);
/// Longest wait for a recovery (a process start, zenoh discovery, on a loaded machine).
const RECOVER_WITHIN: Duration = Duration::from_secs(30);
/// The file-size limit of the recorder whose disk fills up.
const FILE_SIZE_LIMIT: u64 = 64 * 1024;

/// The `mrtwin` binary under test.
fn mrtwin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mrtwin"))
}

/// One process of the matrix, restartable. Life `n` writes its stdout and stderr to
/// `<name><n>.out` and `<name><n>.err` (a pipe nobody reads would stall a chatty process);
/// a process still running when this drops is killed.
struct Proc {
    name: &'static str,
    dir: PathBuf,
    command: Box<dyn Fn(usize) -> Command>,
    child: Option<Child>,
    lives: usize,
}

impl Proc {
    /// A process whose life `n` runs `command(n)`; not started yet.
    fn new(name: &'static str, dir: &Path, command: impl Fn(usize) -> Command + 'static) -> Self {
        Self {
            name,
            dir: dir.to_owned(),
            command: Box::new(command),
            child: None,
            lives: 0,
        }
    }

    /// The log file `ext` (`out` or `err`) of life `life`.
    fn log_path(&self, life: usize, ext: &str) -> PathBuf {
        self.dir.join(format!("{}{life}.{ext}", self.name))
    }

    /// The log `ext` of life `life` (empty when unreadable).
    fn log(&self, life: usize, ext: &str) -> String {
        std::fs::read_to_string(self.log_path(life, ext)).unwrap_or_default()
    }

    /// Start the next life. On Linux the child is killed with this test's thread, so a
    /// test killed outright leaves nothing running.
    fn start(&mut self) {
        assert!(self.child.is_none(), "{} already runs", self.name);
        let life = self.lives;
        let mut cmd = (self.command)(life);
        cmd.stdout(File::create(self.log_path(life, "out")).expect("log file"))
            .stderr(File::create(self.log_path(life, "err")).expect("log file"));
        #[cfg(target_os = "linux")]
        // SAFETY: prctl is async-signal-safe; nothing else runs between fork and exec.
        unsafe {
            cmd.pre_exec(|| {
                libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
                Ok(())
            });
        }
        self.child = Some(
            cmd.spawn()
                .unwrap_or_else(|e| panic!("start {}: {e}", self.name)),
        );
        self.lives += 1;
    }

    /// The current life (the one started last).
    fn life(&self) -> usize {
        self.lives.saturating_sub(1)
    }

    /// Process id of the running child.
    fn pid(&self) -> i32 {
        self.child.as_ref().expect("running").id() as i32
    }

    /// Send `sig` to the running child.
    fn signal(&self, sig: i32) {
        // SAFETY: kill(2) on our own child's pid.
        unsafe {
            libc::kill(self.pid(), sig);
        }
    }

    /// Whether the current life still runs.
    fn alive(&mut self) -> bool {
        self.child
            .as_mut()
            .is_some_and(|c| matches!(c.try_wait(), Ok(None)))
    }

    /// `kill -9`, and reap it.
    fn kill9(&mut self) {
        let mut c = self.child.take().expect("running");
        c.kill().ok();
        c.wait().ok();
    }

    /// Wait at most `timeout` for the current life to exit by itself; `None` (and the
    /// child killed) when it did not.
    fn wait_exit(&mut self, timeout: Duration) -> Option<ExitStatus> {
        let mut c = self.child.take().expect("running");
        let status = wait_until(timeout, Duration::from_millis(20), || {
            c.try_wait().ok().flatten()
        });
        if status.is_none() {
            c.kill().ok();
            c.wait().ok();
        }
        status
    }

    /// SIGINT (Ctrl-C), then wait at most 20 s for the exit.
    fn interrupt(&mut self) -> Option<ExitStatus> {
        self.signal(libc::SIGINT);
        self.wait_exit(Duration::from_secs(20))
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            c.kill().ok();
            c.wait().ok();
        }
    }
}

/// `f()` every `poll` until it gives a value, for at most `timeout`.
fn wait_until<T>(timeout: Duration, poll: Duration, mut f: impl FnMut() -> Option<T>) -> Option<T> {
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(v) = f() {
            return Some(v);
        }
        if Instant::now() >= deadline {
            return None;
        }
        std::thread::sleep(poll);
    }
}

/// One `sensor stream` status of the twin, as it arrived.
#[derive(Debug, Clone)]
struct Health {
    at: Instant,
    level: u8,
    message: String,
    values: BTreeMap<String, String>,
}

impl Health {
    /// The status `s`, arrived at `at`.
    fn from_status(at: Instant, s: &DiagnosticStatus) -> Self {
        Self {
            at,
            level: s.level,
            message: s.message.clone(),
            values: s
                .values
                .iter()
                .map(|kv| (kv.key.clone(), kv.value.clone()))
                .collect(),
        }
    }

    /// A counter of the status (0 when absent).
    fn count(&self, key: &str) -> u64 {
        self.values
            .get(key)
            .and_then(|v| v.parse().ok())
            .unwrap_or(0)
    }

    /// Level name.
    fn level_name(&self) -> &'static str {
        level_name(self.level)
    }
}

/// The name of a `DiagnosticStatus` level byte.
fn level_name(level: u8) -> &'static str {
    ["OK", "WARN", "ERROR", "STALE"]
        .get(usize::from(level))
        .copied()
        .unwrap_or("?")
}

/// This test's zenoh session, listening on the port every process connects to, and
/// collecting the twin's `sensor stream` statuses from `/diagnostics`.
struct Observer {
    seen: Arc<Mutex<Vec<Health>>>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Observer {
    /// Open the session (listening on `port`) and start collecting.
    fn start(damper: &str, port: u16) -> Self {
        let seen = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let (ready_tx, ready_rx) = mpsc::channel();
        let thread = std::thread::spawn({
            let (seen, stop, damper) = (seen.clone(), stop.clone(), damper.to_string());
            move || {
                let zenoh = bridge::zenoh::ZenohConfig {
                    listen: vec![format!("tcp/127.0.0.1:{port}")],
                    multicast_scouting: false,
                    ..Default::default()
                };
                let settings = node::transports::TransportSettings::new(
                    &damper,
                    "/fault_matrix_observer",
                    &Default::default(),
                    &zenoh,
                    &Default::default(),
                );
                let mut t = match node::transports::open(
                    node::transports::TransportKind::Zenoh,
                    &settings,
                    &[],
                    &[Topic::Diagnostics],
                ) {
                    Ok(t) => t,
                    Err(e) => {
                        ready_tx.send(Err(e.to_string())).ok();
                        return;
                    }
                };
                ready_tx.send(Ok(())).ok();
                let mut inbox = Vec::new();
                while !stop.load(Ordering::Relaxed) {
                    inbox.clear();
                    t.poll(&mut inbox).ok();
                    let now = Instant::now();
                    for m in &inbox {
                        if let Message::Diagnostics(d) = m {
                            for s in d
                                .status
                                .iter()
                                .filter(|s| s.name.ends_with("sensor stream"))
                            {
                                seen.lock().unwrap().push(Health::from_status(now, s));
                            }
                        }
                    }
                    std::thread::sleep(Duration::from_millis(10));
                }
            }
        });
        match ready_rx.recv_timeout(Duration::from_secs(30)) {
            Ok(Ok(())) => {}
            Ok(Err(e)) => panic!("the observer's zenoh session: {e}"),
            Err(_) => panic!("the observer's zenoh session did not open within 30 s"),
        }
        Self {
            seen,
            stop,
            thread: Some(thread),
        }
    }

    /// The first status at or after `since` that satisfies `pred`, waiting at most
    /// `timeout` from now.
    fn wait(
        &self,
        since: Instant,
        timeout: Duration,
        pred: impl Fn(&Health) -> bool,
    ) -> Option<Health> {
        wait_until(timeout, Duration::from_millis(20), || {
            self.seen
                .lock()
                .unwrap()
                .iter()
                .find(|h| h.at >= since && pred(h))
                .cloned()
        })
    }

    /// The latest status, if any.
    fn last(&self) -> Option<Health> {
        self.seen.lock().unwrap().last().cloned()
    }
}

impl Drop for Observer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            t.join().ok();
        }
    }
}

/// The controller's latest progress line (see [`fault_matrix_controller_process`]).
fn controller_status(c: &Proc, life: usize) -> Option<serde_json::Value> {
    c.log(life, "out")
        .lines()
        .rev()
        // The harness's "test … " has no newline: the first line starts after it.
        .find_map(|l| serde_json::from_str::<serde_json::Value>(&l[l.find('{')?..]).ok())
}

/// A counter of the controller's latest progress line of `life` (0 before the first).
fn controller_count(c: &Proc, life: usize, key: &str) -> u64 {
    controller_status(c, life)
        .and_then(|v| v[key].as_u64())
        .unwrap_or(0)
}

/// Wait at most `timeout` until the controller's life `life` has more than `above`
/// answers (replies carrying a force).
fn controller_answers_above(c: &Proc, life: usize, above: u64, timeout: Duration) -> Option<u64> {
    wait_until(timeout, Duration::from_millis(100), || {
        let n = controller_count(c, life, "answered");
        (n > above).then_some(n)
    })
}

/// Messages per topic name read from a bag, and what its `metadata.yaml` (rewritten at
/// every flush) says was flushed.
fn read_vs_flushed(bag: &BagContents) -> (BTreeMap<String, u64>, BTreeMap<String, u64>) {
    let read = bag
        .topics
        .iter()
        .map(|t| (t.name.clone(), t.count))
        .collect();
    let flushed = bag
        .metadata
        .iter()
        .flat_map(|m| &m.topics_with_message_count)
        .map(|t| (t.topic_metadata.name.clone(), t.message_count))
        .collect();
    (read, flushed)
}

/// Whether every topic holds at least the messages of the last flush; (read, flushed) totals.
fn keeps_flushed(bag: &BagContents) -> (bool, u64, u64) {
    let (read, flushed) = read_vs_flushed(bag);
    let ok = flushed
        .iter()
        .all(|(name, n)| read.get(name).copied().unwrap_or(0) >= *n);
    (ok, read.values().sum(), flushed.values().sum())
}

/// The `sensor stream` levels a bag's `/diagnostics` recorded, as (level, count).
fn bag_stream_levels(bag: &BagContents) -> BTreeMap<&'static str, u64> {
    let mut levels = BTreeMap::new();
    for m in &bag.messages {
        if let Message::Diagnostics(d) = &m.message {
            for s in d
                .status
                .iter()
                .filter(|s| s.name.ends_with("sensor stream"))
            {
                *levels.entry(level_name(s.level)).or_insert(0) += 1;
            }
        }
    }
    levels
}

/// One row of the matrix.
struct Row {
    fault: &'static str,
    expected: &'static str,
    seen: String,
    pass: bool,
}

/// Seconds from `t0` to `t`, for the table.
fn since(t0: Instant, t: Instant) -> String {
    format!("{:.2} s", t.saturating_duration_since(t0).as_secs_f64())
}

/// The rows as a Markdown table.
fn table(rows: &[Row]) -> String {
    let mut s = String::from("| # | fault | expected | seen | result |\n|---|---|---|---|---|\n");
    for (i, r) in rows.iter().enumerate() {
        s += &format!(
            "| {} | {} | {} | {} | {} |\n",
            i + 1,
            r.fault,
            r.expected,
            r.seen.replace('|', "\\|").replace('\n', " "),
            if r.pass { "pass" } else { "**FAIL**" }
        );
    }
    s
}

/// The matrix: bring-up, the seven faults in turn, a clean stop; the table, then the
/// verdict.
#[test]
fn fault_matrix_of_the_live_system() {
    let started = Instant::now();
    let dir = TempDir::new("fault_matrix");
    let root = dir
        .path("twin.yaml")
        .parent()
        .expect("a directory")
        .to_path_buf();
    let pid = std::process::id();
    let port = free_port();
    let damper = format!("fm{pid}");
    let prefix = format!("mrtwin/fm{pid}");
    // One client and one server on the control service: a dead controller or twin whose
    // ports were not cleaned up would keep its successor out.
    let ice = Iceoryx2Config {
        service_prefix: prefix.clone(),
        max_clients: 1,
        ..Default::default()
    };
    let zen = format!(
        "    zenoh:\n      multicast_scouting: false\n      connect: [\"tcp/127.0.0.1:{port}\"]\n"
    );
    let twin_yaml = dir.path("twin.yaml");
    std::fs::write(
        &twin_yaml,
        format!(
            "mrtwin_twin:\n  ros__parameters:\n    damper: {damper}\n    model: two-chamber\n    transports: [zenoh, iceoryx2]\n    input: zenoh\n    control_service: true\n    stale_after_s: 0.5\n    diagnostics_period_s: 0.25\n{zen}    iceoryx2:\n      service_prefix: {prefix}\n      max_clients: 1\n"
        ),
    )
    .unwrap();
    let stand_text = format!(
        "mrtwin_stand:\n  ros__parameters:\n    damper: {damper}\n    model: two-chamber\n    transports: [zenoh]\n    rate_hz: 500.0\n    currents_a: [0.5, 1.0]\n    frequencies_hz: [1.0, 2.0]\n    segment_duration_s: 10.0\n    noise_n: 5.0\n{zen}"
    );
    let stand_yaml = dir.path("stand.yaml");
    std::fs::write(&stand_yaml, &stand_text).unwrap();
    let burst_yaml = dir.path("burst.yaml");
    std::fs::write(
        &burst_yaml,
        stand_text.replace(
            "    noise_n: 5.0\n",
            "    noise_n: 5.0\n    faults:\n      duplicate_probability: 0.05\n      swap_probability: 0.05\n",
        ),
    )
    .unwrap();
    let rec_yaml = dir.path("recorder.yaml");
    std::fs::write(
        &rec_yaml,
        format!("/**:\n  ros__parameters:\n    damper: {damper}\n{zen}"),
    )
    .unwrap();

    let observer = Observer::start(&damper, port);
    let node_cmd = |yaml: PathBuf, verb: &'static str| {
        move |_life: usize| {
            let mut c = mrtwin();
            c.args([verb, "--ros-args", "--params-file"]).arg(&yaml);
            c
        }
    };
    let mut twin = Proc::new("twin", &root, node_cmd(twin_yaml, "node"));
    let mut stand = Proc::new("stand", &root, node_cmd(stand_yaml, "stand"));
    let mut burst = Proc::new("burst", &root, node_cmd(burst_yaml, "stand"));
    let recorder_cmd =
        |name: &'static str, flush: &'static str, rec_yaml: PathBuf, root: PathBuf| {
            move |life: usize| {
                let mut c = mrtwin();
                c.args([
                    "record",
                    "--transport",
                    "zenoh",
                    "--flush-period",
                    flush,
                    "--out",
                ])
                .arg(root.join(format!("{name}{life}")))
                .args(["--ros-args", "--params-file"])
                .arg(&rec_yaml);
                c
            }
        };
    let mut recorder = Proc::new(
        "recorder",
        &root,
        recorder_cmd("bag", "0.5", rec_yaml.clone(), root.clone()),
    );
    let full_cmd = recorder_cmd("full", "0.25", rec_yaml, root.clone());
    let mut full = Proc::new("full", &root, move |life| {
        let mut c = full_cmd(life);
        // SAFETY: setrlimit is async-signal-safe; nothing else runs between fork and exec.
        unsafe {
            c.pre_exec(|| {
                let lim = libc::rlimit {
                    rlim_cur: FILE_SIZE_LIMIT as libc::rlim_t,
                    rlim_max: FILE_SIZE_LIMIT as libc::rlim_t,
                };
                if libc::setrlimit(libc::RLIMIT_FSIZE, &lim) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
        c
    });
    let ice_json = serde_json::to_string(&ice).unwrap();
    let controller_stop = root.join("controller.stop");
    let controller_cmd = std::rc::Rc::new(move |_life: usize| {
        let mut c = Command::new(std::env::current_exe().expect("test binary"));
        c.args([
            "--exact",
            "fault_matrix_controller_process",
            "--ignored",
            "--nocapture",
            "--test-threads",
            "1",
        ])
        .env(CONTROLLER_ENV, &ice_json)
        .env(CONTROLLER_STOP_ENV, &controller_stop);
        c
    });
    let mut controller = Proc::new("controller", &root, {
        let c = controller_cmd.clone();
        move |life| c(life)
    });

    // Bring-up: the twin sees the stand (health OK) and answers the controller.
    recorder.start();
    twin.start();
    stand.start();
    let up = observer.wait(started, RECOVER_WITHIN * 2, |h| {
        h.level == DiagnosticStatus::OK
    });
    assert!(
        up.is_some(),
        "the system never came up (health {:?}):\ntwin: {}\nstand: {}",
        observer.last(),
        twin.log(0, "err"),
        stand.log(0, "err")
    );
    controller.start();
    assert!(
        controller_answers_above(&controller, 0, 0, RECOVER_WITHIN).is_some(),
        "the controller never got an answer:\n{}\n{}\ntwin: {}",
        controller.log(0, "out"),
        controller.log(0, "err"),
        twin.log(0, "err")
    );
    let twin_pid = twin.pid();
    let mut rows = Vec::new();

    // 1. kill -9 of the stand, restarted.
    rows.push(silence_row(
        &observer,
        &mut twin,
        twin_pid,
        &mut stand,
        [
            "stand: kill -9, restarted 1 s after STALE",
            "the kill",
            "the restart",
        ],
        |stand| stand.kill9(),
        |stand, _| {
            std::thread::sleep(Duration::from_secs(1));
            let t1 = Instant::now();
            stand.start();
            t1
        },
    ));

    // 2. The stand silent: SIGSTOP for 3 s, then SIGCONT.
    rows.push(silence_row(
        &observer,
        &mut twin,
        twin_pid,
        &mut stand,
        ["stand silent: SIGSTOP 3 s, SIGCONT", "SIGSTOP", "SIGCONT"],
        |stand| stand.signal(libc::SIGSTOP),
        |stand, t0| {
            let resume = t0 + Duration::from_secs(3);
            std::thread::sleep(resume.saturating_duration_since(Instant::now()));
            let t1 = Instant::now();
            stand.signal(libc::SIGCONT);
            t1
        },
    ));

    // 3. A burst of duplicated and out-of-order samples: the stand restarted with 5 %
    // duplicates and 5 % swaps for 4 s, then the clean stand again.
    {
        let before = observer.last().expect("health seen");
        let dropped = |h: &Health| h.count("duplicates") + h.count("out_of_order");
        let base = dropped(&before);
        let stopped_clean = stand.interrupt().is_some_and(|s| s.success());
        let t0 = Instant::now();
        burst.start();
        let warn = observer.wait(t0, RECOVER_WITHIN, |h| {
            h.level == DiagnosticStatus::WARN && dropped(h) > base
        });
        std::thread::sleep((t0 + Duration::from_secs(4)).saturating_duration_since(Instant::now()));
        let burst_clean = burst.interrupt().is_some_and(|s| s.success());
        let t1 = Instant::now();
        stand.start();
        let ok = observer.wait(t1, RECOVER_WITHIN, |h| h.level == DiagnosticStatus::OK);
        let after = observer.last().expect("health seen");
        let alive = twin.alive() && twin.pid() == twin_pid;
        rows.push(Row {
            fault: "burst: 4 s of 5 % duplicated and 5 % swapped samples",
            expected:
                "twin runs on; WARN with the duplicates and out-of-order samples counted, OK after",
            seen: format!(
                "{}; duplicates {} → {}, out of order {} → {}; {}; twin {}",
                warn.as_ref().map_or("no WARN".into(), |h| format!(
                    "WARN {} into the burst (\"{}\")",
                    since(t0, h.at),
                    h.message
                )),
                before.count("duplicates"),
                after.count("duplicates"),
                before.count("out_of_order"),
                after.count("out_of_order"),
                ok.as_ref().map_or("never OK again".into(), |h| format!(
                    "OK {} after the clean stand returned",
                    since(t1, h.at)
                )),
                if alive { "alive" } else { "GONE" }
            ),
            pass: warn.is_some() && ok.is_some() && alive && stopped_clean && burst_clean,
        });
    }

    // 4. kill -9 of the twin, restarted while the stand streams (a late joiner). The
    // controller stays up: it must get answers from the new twin, whose control server
    // takes the dead one's place (one server allowed).
    {
        let before = observer.last().expect("health seen");
        let failed =
            |c: &Proc| controller_count(c, 0, "errors") + controller_count(c, 0, "timeouts");
        let failed_before = failed(&controller);
        twin.kill9();
        // Let the controller notice (its requests fail or time out meanwhile).
        std::thread::sleep(Duration::from_secs(1));
        let answered = controller_count(&controller, 0, "answered");
        let t1 = Instant::now();
        twin.start();
        let ok = observer.wait(t1, RECOVER_WITHIN, |h| {
            h.level == DiagnosticStatus::OK && h.count("received") < before.count("received")
        });
        let answers = controller_answers_above(&controller, 0, answered, RECOVER_WITHIN);
        let alive = twin.alive();
        rows.push(Row {
            fault: "twin: kill -9, restarted mid-stream (late joiner)",
            expected: "the new twin gets OK on the running stream; the running controller gets its answers (dead server cleaned up)",
            seen: format!(
                "{}; controller {}; new twin {}",
                ok.as_ref().map_or("never OK".into(), |h| format!(
                    "OK {} after the restart ({} samples received, the old twin had {})",
                    since(t1, h.at),
                    h.count("received"),
                    before.count("received")
                )),
                answers.map_or(
                    format!("got no answer after the restart (stuck at {answered})"),
                    |n| format!(
                        "failed {} requests while the twin was down, then answered again ({answered} → {n})",
                        failed(&controller) - failed_before
                    )
                ),
                if alive { "alive" } else { "GONE" }
            ),
            pass: ok.is_some() && answers.is_some() && alive,
        });
    }
    let twin_pid = twin.pid();

    // 5. kill -9 of the controller, restarted: its client port must be cleaned up, or the
    // new one finds the control service full (one client allowed).
    {
        // The limit holds: a second controller beside the running one is refused.
        let mut probe = Proc::new("probe", &root, {
            let c = controller_cmd.clone();
            move |life| c(life)
        });
        probe.start();
        let probe_exit = probe.wait_exit(RECOVER_WITHIN);
        let refused =
            controller_status(&probe, 0).and_then(|v| v["fatal"].as_str().map(str::to_string));
        let old_answers = controller_count(&controller, 0, "answered");
        controller.kill9();
        let t1 = Instant::now();
        controller.start();
        let life = controller.life();
        let answers = controller_answers_above(&controller, life, 0, RECOVER_WITHIN);
        let health = observer.last();
        let alive = twin.alive() && twin.pid() == twin_pid;
        let err = controller.log(life, "out");
        rows.push(Row {
            fault: "controller (iceoryx2 client): kill -9, restarted",
            expected: "the new controller connects and gets answers (dead client cleaned up); twin runs on",
            seen: format!(
                "a second controller beside the running one: {}; {}; twin {}, health {}",
                match (&refused, probe_exit) {
                    (Some(why), Some(_)) => format!("refused (\"{why}\")"),
                    _ => format!(
                        "NOT refused (exit {probe_exit:?}: {})",
                        tail(&(probe.log(0, "out") + &probe.log(0, "err")), 6)
                    ),
                },
                answers.map_or_else(
                    || format!("the new controller got no answer: {}", err.lines().last().unwrap_or("")),
                    |n| format!(
                        "the killed one had {old_answers} answers, the new one {n} within {}",
                        since(t1, Instant::now())
                    )
                ),
                if alive { "alive" } else { "GONE" },
                health.map_or("?", |h| h.level_name())
            ),
            pass: refused.is_some() && answers.is_some() && alive,
        });
    }

    // 6. kill -9 of the recorder, restarted into a new bag.
    {
        recorder.kill9();
        let bag0 = root.join("bag0");
        let read = read_bag(&bag0);
        recorder.start();
        let bag1 = root.join(format!("bag{}", recorder.life()));
        let recording = wait_until(RECOVER_WITHIN, Duration::from_millis(500), || {
            read_bag(&bag1)
                .ok()
                .and_then(|b| b.metadata)
                .filter(|m| m.message_count > 0)
                .map(|m| m.message_count)
        });
        let alive = twin.alive() && twin.pid() == twin_pid;
        let (seen, pass) = match &read {
            Ok(bag) => {
                let (keeps, n_read, n_flushed) = keeps_flushed(bag);
                let levels = bag_stream_levels(bag);
                let shows = ["STALE", "WARN", "OK"]
                    .iter()
                    .all(|l| levels.contains_key(l));
                (
                    format!(
                        "killed bag reads {n_read} messages, its last flush had {n_flushed}; its `sensor stream` statuses {levels:?}; {}; twin {}",
                        recording.map_or("the new recorder wrote nothing".into(), |n| format!(
                            "the new recorder flushed {n} messages"
                        )),
                        if alive { "alive" } else { "GONE" }
                    ),
                    keeps && n_flushed > 0 && shows && recording.is_some() && alive,
                )
            }
            Err(e) => (
                format!("the killed recorder's bag does not read: {e}"),
                false,
            ),
        };
        rows.push(Row {
            fault: "recorder: kill -9, restarted into a new bag",
            expected: "the killed bag reads back every message of its last flush (and rows 1–3 in its /diagnostics); the new one records",
            seen,
            pass,
        });
    }

    // 7. A recorder whose disk fills up: a file-size limit of 64 KiB (the main recorder
    // keeps recording beside it).
    {
        full.start();
        let status = full.wait_exit(RECOVER_WITHIN * 2);
        let err = full.log(0, "err");
        let mcap = root.join("full0").join("full0_0.mcap");
        let line = err
            .lines()
            .find(|l| l.starts_with("error:"))
            .unwrap_or("")
            .to_string();
        let names_it =
            line.contains(&mcap.display().to_string()) && line.contains("File too large");
        let exit_ok = status.is_some_and(|s| s.code() == Some(1));
        let read = read_bag(&root.join("full0"));
        let alive = twin.alive() && twin.pid() == twin_pid && recorder.alive();
        let (kept, pass_bag) = match &read {
            Ok(bag) => {
                let (keeps, n_read, n_flushed) = keeps_flushed(bag);
                (
                    format!(
                        "the bag ({} bytes) reads {n_read} messages, its last flush had {n_flushed}",
                        std::fs::metadata(&mcap).map_or(0, |m| m.len())
                    ),
                    keeps && n_flushed > 0,
                )
            }
            Err(e) => (format!("the bag does not read: {e}"), false),
        };
        rows.push(Row {
            fault: "recorder's disk full: a 64 KiB file-size limit (RLIMIT_FSIZE)",
            expected: "the recorder exits 1 with a message naming the file and the cause; the bag reads back every message of its last flush",
            seen: format!(
                "{}: `{}`; {kept}; twin and main recorder {}",
                match status {
                    Some(s) => match (s.code(), s.signal()) {
                        (Some(c), _) => format!("exit {c}"),
                        (None, Some(sig)) => format!("killed by signal {sig}"),
                        _ => "?".into(),
                    },
                    None => "did not stop".into(),
                },
                line.trim_start_matches("error: ")
                    .replace(&format!("{}/", root.display()), ""),
                if alive { "alive" } else { "GONE" }
            ),
            pass: names_it && exit_ok && pass_bag && alive,
        });
    }

    // 8. Everything stopped (the controller by its stop file, the rest with Ctrl-C):
    // clean exits, the last bag finished.
    {
        std::fs::write(root.join("controller.stop"), "").unwrap();
        let controller_ok = controller
            .wait_exit(Duration::from_secs(20))
            .is_some_and(|s| s.success());
        let stand_ok = stand.interrupt().is_some_and(|s| s.success());
        let twin_ok = twin.interrupt().is_some_and(|s| s.success());
        let twin_out = twin.log(twin.life(), "out");
        let rec_ok = recorder.interrupt().is_some_and(|s| s.success());
        let bag = root.join(format!("bag{}", recorder.life()));
        let (seen_bag, bag_ok) = match read_bag(&bag) {
            Ok(b) => {
                let (_, n_read, n_flushed) = keeps_flushed(&b);
                (
                    format!(
                        "the last bag reads {n_read} messages, its metadata.yaml says {n_flushed}"
                    ),
                    n_read == n_flushed && n_read > 0 && b.notes.is_empty(),
                )
            }
            Err(e) => (format!("the last bag does not read: {e}"), false),
        };
        rows.push(Row {
            fault: "clean stop: the controller, then Ctrl-C to stand, twin and recorder",
            expected: "each exits 0; the last bag is complete",
            seen: format!(
                "controller {}, stand {}, twin {}, recorder {}; {seen_bag}; twin: {}",
                if controller_ok { "exit 0" } else { "FAILED" },
                if stand_ok { "exit 0" } else { "FAILED" },
                if twin_ok { "exit 0" } else { "FAILED" },
                if rec_ok { "exit 0" } else { "FAILED" },
                twin_out
                    .lines()
                    .find(|l| l.contains("stopped"))
                    .unwrap_or("")
                    .trim()
            ),
            pass: controller_ok && stand_ok && twin_ok && rec_ok && bag_ok,
        });
    }
    let timeline = observer.seen.lock().unwrap().clone();
    drop(observer);

    let text = format!(
        "\n## Fault matrix ({:.0} s)\n\n{}",
        started.elapsed().as_secs_f64(),
        table(&rows)
    );
    // Past the harness's capture: the table is the test's report.
    std::io::stderr().write_all(text.as_bytes()).ok();
    if let Ok(path) = std::env::var("MRTWIN_FAULT_MATRIX_TABLE") {
        std::fs::write(path, &text).ok();
    }
    let failed: Vec<usize> = rows
        .iter()
        .enumerate()
        .filter(|(_, r)| !r.pass)
        .map(|(i, _)| i + 1)
        .collect();
    if !failed.is_empty() {
        eprintln!("--- the twin's `sensor stream`, s since the start:");
        for h in &timeline {
            eprintln!("{} {} {}", since(started, h.at), h.level_name(), h.message);
        }
        for p in [&twin, &stand, &burst, &recorder, &controller, &full] {
            for life in 0..p.lives {
                eprintln!(
                    "--- {}{life} stderr:\n{}",
                    p.name,
                    tail(&p.log(life, "err"), 20)
                );
            }
        }
        panic!("fault matrix rows {failed:?} failed:{text}");
    }
}

/// The last `n` lines of `s`.
/// A fault that silences `stand` (`silence`, at t0), then ends (`resume`, given t0,
/// returns when it resumed): `sensor stream` STALE within [`SHOW_WITHIN`] of t0, then OK
/// within [`RECOVER_WITHIN`] with more samples received, and the twin the same process
/// throughout. `labels`: the row's fault, what silenced, what resumed.
fn silence_row(
    observer: &Observer,
    twin: &mut Proc,
    twin_pid: i32,
    stand: &mut Proc,
    labels: [&'static str; 3],
    silence: impl FnOnce(&mut Proc),
    resume: impl FnOnce(&mut Proc, Instant) -> Instant,
) -> Row {
    let [fault, silenced, resumed] = labels;
    let t0 = Instant::now();
    silence(stand);
    let stale = observer.wait(t0, SHOW_WITHIN, |h| h.level == DiagnosticStatus::STALE);
    let t1 = resume(stand, t0);
    let base = stale.as_ref().map_or(0, |h| h.count("received"));
    let ok = observer.wait(t1, RECOVER_WITHIN, |h| {
        h.level == DiagnosticStatus::OK && h.count("received") > base
    });
    let alive = twin.alive() && twin.pid() == twin_pid;
    Row {
        fault,
        expected: "twin runs on; `sensor stream` STALE while the stand is silent, OK after",
        seen: format!(
            "{}; {}; twin {}",
            stale.as_ref().map_or("no STALE".into(), |h| format!(
                "STALE {} after {silenced} (\"{}\")",
                since(t0, h.at),
                h.message
            )),
            ok.as_ref().map_or("never OK again".into(), |h| format!(
                "OK {} after {resumed} ({} samples received meanwhile)",
                since(t1, h.at),
                h.count("received") - base
            )),
            if alive { "alive" } else { "GONE" }
        ),
        pass: stale.is_some() && ok.is_some() && alive,
    }
}

fn tail(s: &str, n: usize) -> String {
    let lines: Vec<&str> = s.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}

/// The controller of the matrix when started by it (with [`CONTROLLER_ENV`]); otherwise
/// nothing. A separate process using [`ControlClient`]: planned-current what-ifs at
/// 50 Hz (what-ifs do not step the twin, whose samples come from the stand), every reply
/// awaited for at most 200 ms; a failed request (no server) is counted and retried next
/// cycle. Every 250 ms a JSON line with its counters. It stops when its stop file
/// ([`CONTROLLER_STOP_ENV`]) appears, when its parent is gone, or after 10 minutes.
#[test]
#[ignore = "a helper process of fault_matrix_of_the_live_system, started by it"]
fn fault_matrix_controller_process() {
    let Ok(json) = std::env::var(CONTROLLER_ENV) else {
        return;
    };
    let cfg: Iceoryx2Config = serde_json::from_str(&json).expect("iceoryx2 config");
    bridge::iceoryx2::quiet_logs();
    let stop_file = PathBuf::from(std::env::var_os(CONTROLLER_STOP_ENV).expect("stop file"));
    let parent = std::os::unix::process::parent_id();
    let started = Instant::now();
    let mut client = match ControlClient::new(&cfg) {
        Ok(c) => c,
        Err(e) => {
            println!("{}", serde_json::json!({ "fatal": e.to_string() }));
            panic!("no control client: {e}");
        }
    };
    let period = Duration::from_millis(20);
    let (mut sent, mut answered, mut rejected, mut timeouts, mut errors) =
        (0u64, 0u64, 0u64, 0u64, 0u64);
    let mut last_error = String::new();
    let mut next_report = started;
    let mut next = started;
    while started.elapsed() < Duration::from_secs(600)
        && std::os::unix::process::parent_id() == parent
        && !stop_file.exists()
    {
        // A late cycle (a reply timed out) starts the schedule anew, without a catch-up burst.
        next = (next + period).max(Instant::now());
        let now_ns = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as i64);
        sent += 1;
        let req = ShmRequest {
            kind: ShmRequest::PLANNED_CURRENT,
            reserved: 0,
            sample: ShmSample {
                seq: sent,
                time_ns: now_ns,
                displacement_m: 0.005,
                velocity_m_s: 0.05,
                force_n: f64::NAN,
                current_a: 1.5,
                temperature_c: f64::NAN,
            },
        };
        match client.request_within(&req, Duration::from_millis(200)) {
            Ok(Some(r)) if r.seq == sent && r.rejected == 0 => answered += 1,
            Ok(Some(_)) => rejected += 1,
            Ok(None) => timeouts += 1,
            Err(e) => {
                errors += 1;
                last_error = e.to_string();
            }
        }
        if Instant::now() >= next_report {
            next_report += Duration::from_millis(250);
            println!(
                "{}",
                serde_json::json!({
                    "t": started.elapsed().as_secs_f64(), "sent": sent, "answered": answered,
                    "rejected": rejected, "timeouts": timeouts, "errors": errors,
                    "last_error": last_error,
                })
            );
        }
        std::thread::sleep(next.saturating_duration_since(Instant::now()));
    }
}
