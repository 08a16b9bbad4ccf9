//! `mrtwin node`, `mrtwin stand` and `mrtwin launch`: the live system.
//!
//! Each node accepts ROS 2 style arguments after `--ros-args`
//! (`--params-file F`, `-r __node:=N`, `-r __ns:=NS`, `-p key:=value`), so `ros2 launch`
//! could start it as well as `mrtwin launch`.

use std::path::PathBuf;
use std::process::{Child, Command};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::Args;
use launch_config::{load_launch, load_node_params, parse_ros_args, LaunchEntry};
use node::config::{TwinNodeParams, STAND_NODE, TWIN_NODE};
use node::runner::{StopWhen, TwinNode};
use node::stand::{StandNode, StandParams};

use crate::live::live_line;
use crate::stop::stop_flag;

/// Arguments of `mrtwin node` and `mrtwin stand`.
#[derive(Debug, Args)]
pub struct NodeArgs {
    /// Stop after this many seconds (default: run until Ctrl-C).
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
    /// Print a live line per second.
    #[arg(long)]
    pub verbose: bool,
    /// Twin node only: serve a Foxglove live view on `[HOST:]PORT` (a bare port is
    /// loopback; 0 picks a free one).
    #[arg(long, value_name = "[HOST:]PORT")]
    pub foxglove: Option<String>,
    /// ROS 2 arguments: `--ros-args --params-file F -r __node:=N -r __ns:=NS -p k:=v`.
    #[arg(
        trailing_var_arg = true,
        allow_hyphen_values = true,
        value_name = "--ros-args …"
    )]
    pub ros_args: Vec<String>,
}

/// The node's parameter files, re-read when their contents change (the `-p` overrides
/// applied again): a running twin takes an upgraded file without a restart.
fn params_file_watch(ros: launch_config::RosArgs) -> node::runner::ParamsSource {
    let read = |ros: &launch_config::RosArgs| -> Vec<Option<Vec<u8>>> {
        ros.params_files
            .iter()
            .map(|f| std::fs::read(f).ok())
            .collect()
    };
    let mut seen = read(&ros);
    Box::new(move || {
        let now = read(&ros);
        if now == seen {
            return None;
        }
        seen = now;
        Some(load_node_params::<TwinNodeParams>(&ros, TWIN_NODE).map_err(|e| e.to_string()))
    })
}

pub(crate) fn duration(d: Option<f64>) -> Result<Option<Duration>> {
    match d {
        None => Ok(None),
        Some(s) if s.is_finite() && s > 0.0 => Ok(Some(Duration::from_secs_f64(s))),
        Some(s) => bail!("--duration must be a positive number of seconds, got {s}"),
    }
}

/// `mrtwin node`.
pub fn run_twin(args: &NodeArgs) -> Result<()> {
    let ros = parse_ros_args(&args.ros_args)?;
    let params: TwinNodeParams = load_node_params(&ros, TWIN_NODE)?;
    let name = ros.fully_qualified_name(TWIN_NODE);
    let stop = stop_flag()?;
    let mut node =
        TwinNode::new(params, &name).with_context(|| format!("start twin node {name}"))?;
    if !ros.params_files.is_empty() {
        node.watch_params(params_file_watch(ros.clone()));
    }
    if let Some(spec) = &args.foxglove {
        crate::foxglove::attach(&mut node, spec, &name)?;
    }
    tracing::info!(node = %name, "running (Ctrl-C stops)");
    let deadline = duration(args.duration)?.map(|d| Instant::now() + d);
    let verbose = args.verbose;
    let last = node.run(
        StopWhen {
            flag: Some(&stop),
            deadline,
        },
        &mut |s| {
            if verbose {
                println!("{}", live_line(s));
            }
        },
    );
    let c = last.counters;
    println!(
        "{name}: stopped after {:.1} s: {} samples received, {} stepped, {} dropped (NaN {}, duplicate {}, out of order {}), {} gaps, {} control requests",
        last.elapsed_s,
        c.received,
        c.accepted,
        c.non_finite + c.duplicates + c.out_of_order,
        c.non_finite,
        c.duplicates,
        c.out_of_order,
        c.gaps,
        last.control_requests
    );
    Ok(())
}

/// `mrtwin stand`.
pub fn run_stand(args: &NodeArgs) -> Result<()> {
    if args.foxglove.is_some() {
        bail!("--foxglove is served by the twin node (mrtwin node), not the stand");
    }
    let ros = parse_ros_args(&args.ros_args)?;
    let params: StandParams = load_node_params(&ros, STAND_NODE)?;
    let name = ros.fully_qualified_name(STAND_NODE);
    let stop = stop_flag()?;
    let mut stand =
        StandNode::new(params, &name).with_context(|| format!("start stand node {name}"))?;
    tracing::info!(node = %name, "playing (Ctrl-C stops)");
    let s = stand.run(Some(&stop), duration(args.duration)?)?;
    println!(
        "{name}: stopped: {} samples generated, {} messages published, {} errors, max lateness {:.2} ms",
        s.generated,
        s.published,
        s.errors,
        s.max_lateness_s * 1e3
    );
    Ok(())
}

/// Arguments of `mrtwin launch`.
#[derive(Debug, Args)]
pub struct LaunchArgs {
    /// Launch file (ROS 2 launch YAML style).
    pub file: PathBuf,
    /// Stop everything after this many seconds.
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
}

/// `mrtwin launch FILE`: start every node as a child process, stop them all on Ctrl-C
/// (or when one fails).
pub fn run_launch(args: &LaunchArgs) -> Result<()> {
    let file = load_launch(&args.file)?;
    let base = args.file.parent().map(PathBuf::from).unwrap_or_default();
    let exe = std::env::current_exe().context("locate the mrtwin executable")?;
    let stop = stop_flag()?;
    let mut children: Vec<(String, Child)> = Vec::new();
    for LaunchEntry { node: n } in &file.launch {
        let sub = match n.exec.as_str() {
            "twin" => "node",
            other => other,
        };
        let mut cmd = Command::new(&exe);
        cmd.arg(sub);
        if let Some(extra) = &n.args {
            cmd.args(extra.split_whitespace());
        }
        cmd.args(n.ros_args(&base));
        let label = n.name.clone().unwrap_or_else(|| n.exec.clone());
        let child = cmd.spawn().with_context(|| format!("start {label}"))?;
        tracing::info!(node = %label, pid = child.id(), "started");
        children.push((label, child));
    }
    let until = StopWhen {
        flag: Some(&stop),
        deadline: duration(args.duration)?.map(|d| Instant::now() + d),
    };
    let mut failed = None;
    'wait: loop {
        if until.reached(Instant::now()) {
            break;
        }
        for (label, c) in &mut children {
            if let Some(status) = c.try_wait()? {
                if !status.success() {
                    failed = Some(format!("{label} exited with {status}"));
                }
                break 'wait;
            }
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    for (_, c) in &mut children {
        // SIGINT: each node shuts down cleanly and leaves the ROS graph.
        let _ = Command::new("kill")
            .args(["-INT", &c.id().to_string()])
            .status();
    }
    let until = Instant::now() + Duration::from_secs(10);
    for (label, c) in &mut children {
        loop {
            if c.try_wait()?.is_some() {
                break;
            }
            if Instant::now() > until {
                tracing::warn!(node = %label, "did not stop in 10 s, killing it");
                let _ = c.kill();
                let _ = c.wait();
                break;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    match failed {
        Some(f) => bail!("{f}"),
        None => Ok(()),
    }
}
