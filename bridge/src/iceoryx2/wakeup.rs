//! Wake-ups for the shared-memory services: each data service `<name>` has a companion
//! event service `<name>/wake`. mrtwin's senders (publishers, control clients) notify it
//! after every send; a receiver's [`WakeListener`] thread waits on it and rings the
//! receiving loop's [`Doorbell`], so that loop sleeps instead of polling shared memory.
//!
//! A sender that does not notify (a foreign iceoryx2 publisher) still gets through: the
//! receiver reads at its next wake-up, which the node's loop schedules at least every
//! [`crate::wake`] deadline it has (STALE, diagnostics, statistics).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::Node;

use super::adapter::{dbg_err, service_name, Svc};
use crate::transport::TransportError;
use crate::wake::Doorbell;

/// How often a listener thread looks whether its owner is gone.
const STOP_CHECK: Duration = Duration::from_millis(50);

/// The name of `service`'s companion event service.
fn wake_service_name(service: &str) -> String {
    format!("{service}/wake")
}

/// Open or create `<service>/wake` for `senders` notifiers and `receivers` listeners
/// (same limits on every side, as for the data services).
fn open<S: iceoryx2::service::Service>(
    node: &Node<S>,
    service: &str,
    senders: usize,
    receivers: usize,
) -> Result<iceoryx2::service::port_factory::event::PortFactory<S>, TransportError> {
    let name = wake_service_name(service);
    node.service_builder(&service_name(&name)?)
        .event()
        .max_notifiers(senders)
        .max_listeners(receivers)
        .max_nodes(senders + receivers + 4)
        .open_or_create()
        .map_err(|e| dbg_err(format!("open or create service `{name}`"), e))
}

/// The sender's side: notify after each send (`S`, the sender's service variant).
#[derive(Debug)]
pub(super) struct WakeNotifier<S: iceoryx2::service::Service = Svc> {
    notifier: Notifier<S>,
    service: String,
}

impl<S: iceoryx2::service::Service> WakeNotifier<S> {
    /// A notifier on `<service>/wake`.
    pub(super) fn new(
        node: &Node<S>,
        service: &str,
        senders: usize,
        receivers: usize,
    ) -> Result<Self, TransportError> {
        let notifier = open(node, service, senders, receivers)?
            .notifier_builder()
            .create()
            .map_err(|e| dbg_err(format!("notifier on `{}`", wake_service_name(service)), e))?;
        Ok(Self {
            notifier,
            service: service.to_string(),
        })
    }

    /// Wake the receivers (the data is already sent when this fails).
    pub(super) fn notify(&self) -> Result<(), TransportError> {
        self.notifier.notify().map(|_| ()).map_err(|e| {
            dbg_err(
                format!("wake-up on `{}` (the data was sent)", self.service),
                e,
            )
        })
    }
}

/// The receiver's side: a thread that rings `doorbell` on every notification of
/// `<service>/wake`; stopped and joined on drop (within [`STOP_CHECK`]).
#[derive(Debug)]
pub(super) struct WakeListener {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl WakeListener {
    /// Listen on `<service>/wake`, ringing `doorbell`.
    pub(super) fn spawn(
        node: &Node<Svc>,
        service: &str,
        senders: usize,
        receivers: usize,
        doorbell: Doorbell,
    ) -> Result<Self, TransportError> {
        let name = wake_service_name(service);
        let listener: Listener<Svc> = open(node, service, senders, receivers)?
            .listener_builder()
            .create()
            .map_err(|e| dbg_err(format!("listener on `{name}`"), e))?;
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let stop = stop.clone();
            let service = name.clone();
            std::thread::Builder::new()
                .name("iceoryx2-wake".into())
                .spawn(move || {
                    while !stop.load(Ordering::Relaxed) {
                        match listener.timed_wait(|_| {}, STOP_CHECK) {
                            Ok(0) => {}
                            Ok(_) => doorbell.ring(),
                            Err(e) => {
                                // The receiver still polls on its deadlines; say why the
                                // wake-ups stopped and stop waiting.
                                tracing::warn!(%service, error = ?e, "wake-up listener failed");
                                doorbell.ring();
                                return;
                            }
                        }
                    }
                })
                .map_err(|e| dbg_err(format!("thread for `{name}`"), e))?
        };
        Ok(Self {
            stop,
            thread: Some(thread),
        })
    }
}

impl Drop for WakeListener {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
