//! Logging, set up once in the binary: `tracing` events in the ROS 2 console format
//! (`[LEVEL] [seconds.nanoseconds] [logger]: message key=value …`) on standard error.
//! `--log-level` sets the level of mrtwin's own crates; the middleware libraries log
//! warnings and errors only, so their chatter does not bury the node's.

use std::fmt;
use std::time::{SystemTime, UNIX_EPOCH};

use clap::ValueEnum;
use tracing::{Event, Level, Subscriber};
use tracing_subscriber::filter::{LevelFilter, Targets};
use tracing_subscriber::fmt::format::Writer;
use tracing_subscriber::fmt::{FmtContext, FormatEvent, FormatFields};
use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::registry::LookupSpan;
use tracing_subscriber::util::SubscriberInitExt;

/// `--log-level`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LogLevel {
    /// Everything.
    Debug,
    /// What the user should see (default).
    Info,
    /// Problems that do not stop the command.
    Warn,
    /// Failures only.
    Error,
}

impl LogLevel {
    fn filter(self) -> LevelFilter {
        match self {
            LogLevel::Debug => LevelFilter::DEBUG,
            LogLevel::Info => LevelFilter::INFO,
            LogLevel::Warn => LevelFilter::WARN,
            LogLevel::Error => LevelFilter::ERROR,
        }
    }
}

/// mrtwin's crates, logged at `--log-level`; everything else at WARN.
const OWN_CRATES: [&str; 8] = [
    "mrtwin",
    "node",
    "bridge",
    "twin",
    "estimation",
    "diagnose",
    "launch_config",
    "msgs",
];

/// Install the subscriber; `logger` names the lines (the node or the subcommand).
pub fn init(level: LogLevel, logger: &str) {
    let mut targets = Targets::new().with_default(LevelFilter::WARN.min(level.filter()));
    for c in OWN_CRATES {
        targets = targets.with_target(c, level.filter());
    }
    let format = RosFormat {
        logger: logger.trim_start_matches('/').to_string(),
    };
    let layer = tracing_subscriber::fmt::layer()
        .with_writer(std::io::stderr)
        .event_format(format);
    // A second init (tests calling main twice) keeps the first subscriber.
    let _ = tracing_subscriber::registry()
        .with(layer.with_filter(targets))
        .try_init();
}

use tracing_subscriber::Layer as _;

/// The ROS 2 console format.
struct RosFormat {
    logger: String,
}

impl<S, N> FormatEvent<S, N> for RosFormat
where
    S: Subscriber + for<'a> LookupSpan<'a>,
    N: for<'a> FormatFields<'a> + 'static,
{
    fn format_event(
        &self,
        ctx: &FmtContext<'_, S, N>,
        mut writer: Writer<'_>,
        event: &Event<'_>,
    ) -> fmt::Result {
        let level = match *event.metadata().level() {
            Level::ERROR => "ERROR",
            Level::WARN => "WARN",
            Level::INFO => "INFO",
            Level::DEBUG | Level::TRACE => "DEBUG",
        };
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        write!(
            writer,
            "[{level}] [{}.{:09}] [{}]: ",
            now.as_secs(),
            now.subsec_nanos(),
            self.logger
        )?;
        ctx.field_format().format_fields(writer.by_ref(), event)?;
        writeln!(writer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_map_to_filters_in_order() {
        let order = [
            LogLevel::Error,
            LogLevel::Warn,
            LogLevel::Info,
            LogLevel::Debug,
        ];
        for w in order.windows(2) {
            assert!(w[0].filter() < w[1].filter(), "{w:?}");
        }
    }
}
