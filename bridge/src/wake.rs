//! Wake-ups on arrival: a [`Doorbell`] that an adapter rings when a message arrives on
//! one of its subscriptions, so the loop that owns the adapter can sleep until then
//! instead of polling on a timer.
//!
//! The doorbell wakes a thread (it is `std::thread::park`/`unpark` underneath): the loop
//! [`Doorbell::bind`]s its own thread to the doorbells of every source it reads, then
//! sleeps with [`wait_until`] after a poll found nothing. A ring while the thread is
//! awake is kept (the next wait returns at once), so no arrival between a poll and the
//! wait is missed; a ring costs an atomic swap when the thread is not asleep.
//!
//! Who rings: zenoh's subscriber callback, RustDDS's reader waker (ROS 2), and for
//! iceoryx2 a listener thread on the service's companion event service, which every
//! mrtwin publisher notifies after it sends (see `iceoryx2`'s module docs).

use std::sync::{Arc, Mutex, PoisonError};
use std::task::{Wake, Waker};
use std::thread::Thread;
use std::time::Instant;

/// A handle that wakes the thread bound to it. Clones ring the same thread.
#[derive(Debug, Clone, Default)]
pub struct Doorbell {
    thread: Arc<Mutex<Option<Thread>>>,
}

impl Doorbell {
    /// A doorbell bound to no thread yet (a ring before [`Doorbell::bind`] is lost, which
    /// is harmless: the first thing a loop does after binding is poll).
    pub fn new() -> Self {
        Self::default()
    }

    /// Wake the calling thread on the next ring (replaces any earlier binding).
    pub fn bind_current_thread(&self) {
        *self.thread.lock().unwrap_or_else(PoisonError::into_inner) = Some(std::thread::current());
    }

    /// Wake the bound thread: now if it sleeps in [`wait_until`], else at its next wait.
    pub fn ring(&self) {
        if let Some(t) = self
            .thread
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .as_ref()
        {
            t.unpark();
        }
    }

    /// A [`Waker`] that rings this doorbell (for readers that wake async tasks).
    pub fn waker(&self) -> Waker {
        Waker::from(Arc::new(self.clone()))
    }
}

impl Wake for Doorbell {
    fn wake(self: Arc<Self>) {
        self.ring();
    }

    fn wake_by_ref(self: &Arc<Self>) {
        self.ring();
    }
}

/// Sleep the calling thread until a doorbell bound to it rings or `deadline` passes
/// (whichever is first; it may also return early, spuriously). Returns at once when a
/// ring came since the last wait, and consumes it.
pub fn wait_until(deadline: Instant) {
    // A deadline already passed still consumes a pending ring (park with a zero timeout).
    std::thread::park_timeout(deadline.saturating_duration_since(Instant::now()));
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn a_ring_from_another_thread_ends_the_wait_long_before_its_deadline() {
        let bell = Doorbell::new();
        bell.bind_current_thread();
        let ringer = {
            let bell = bell.clone();
            std::thread::spawn(move || {
                std::thread::sleep(Duration::from_millis(20));
                bell.ring();
            })
        };
        let t0 = Instant::now();
        wait_until(t0 + Duration::from_secs(30));
        // Bounded: a lost ring would sleep 30 s; the ring comes after 20 ms.
        assert!(t0.elapsed() < Duration::from_secs(10), "{:?}", t0.elapsed());
        ringer.join().unwrap();
    }

    #[test]
    fn a_ring_while_awake_is_kept_for_the_next_wait() {
        let bell = Doorbell::new();
        bell.bind_current_thread();
        bell.waker().wake_by_ref();
        let t0 = Instant::now();
        wait_until(t0 + Duration::from_secs(30));
        assert!(t0.elapsed() < Duration::from_secs(10), "{:?}", t0.elapsed());
    }
}
