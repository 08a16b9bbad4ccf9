//! Stopping on Ctrl-C or SIGTERM: a flag the long-running commands check every loop turn.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::{Context, Result};

/// Ctrl-C / SIGTERM set this flag; the nodes stop at their next loop turn.
pub fn stop_flag() -> Result<Arc<AtomicBool>> {
    let flag = Arc::new(AtomicBool::new(false));
    let f = flag.clone();
    ctrlc::set_handler(move || f.store(true, Ordering::Relaxed))
        .context("install the Ctrl-C handler")?;
    Ok(flag)
}
