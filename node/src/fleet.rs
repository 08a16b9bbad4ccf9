//! Many dampers in one process: N stands played by one paced loop, N twin cores served by
//! another, each damper on its own transport (its own key expressions), all of them the
//! same code as the single nodes — [`StandPlayer`] for the stand, [`TwinCore`] for the twin.
//!
//! One thread per side rather than one per damper: at 1 kHz, fifty dampers are 50 000
//! samples a second, and a loop over the cores that sleeps on all their doorbells at once
//! wakes once per burst instead of once per damper.

use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use bridge::transport::{Message, Transport};

use crate::conditioning::SensorSample;
use crate::config::TwinNodeParams;
use crate::core::TwinCore;
use crate::runner::{NodeError, StopWhen};
use crate::stand::{publish_sample, run_paced, StandParams, StandPlayer, StandSummary};

/// Longest sleep of the twins' loop between turns (how soon a stop is seen).
const MAX_SLEEP: Duration = Duration::from_millis(20);

/// One damper's twin in a fleet.
struct Member {
    core: TwinCore,
    transport: Box<dyn Transport>,
    received: u64,
    stepped: u64,
    errors: u64,
}

/// What one twin of the fleet did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TwinCounts {
    /// Samples that arrived on its transport.
    pub received: u64,
    /// Samples its core stepped (accepted by its conditioning).
    pub stepped: u64,
    /// Transport errors (publish or poll), each logged.
    pub errors: u64,
}

/// N twin cores over N transports, served by one loop.
pub struct FleetTwins {
    members: Vec<Member>,
    inbox: Vec<Message>,
}

impl FleetTwins {
    /// One twin per `(parameters, node name, transport)`; each transport subscribes to its
    /// damper's samples and publishes its outputs.
    pub fn new(
        members: Vec<(TwinNodeParams, String, Box<dyn Transport>)>,
    ) -> Result<Self, NodeError> {
        let members = members
            .into_iter()
            .map(|(params, name, transport)| {
                Ok(Member {
                    core: TwinCore::new(&params, &name)?,
                    transport,
                    received: 0,
                    stepped: 0,
                    errors: 0,
                })
            })
            .collect::<Result<Vec<_>, NodeError>>()?;
        Ok(Self {
            members,
            inbox: Vec::new(),
        })
    }

    /// Serve every twin until `stop`: poll each transport, step each sample on its core
    /// with the wall clock, publish what the core returns (and its diagnostics when due)
    /// on the same transport; sleep on all doorbells when nothing came.
    pub fn run(&mut self, stop: StopWhen<'_>) -> Vec<TwinCounts> {
        let start = Instant::now();
        let mut rings = true;
        for m in &self.members {
            match m.transport.doorbell() {
                Some(b) => b.bind_current_thread(),
                None => rings = false,
            }
        }
        loop {
            let now = Instant::now();
            if stop.reached(now) {
                break;
            }
            let t = now.duration_since(start).as_secs_f64();
            let mut busy = false;
            let mut due = f64::INFINITY;
            for m in &mut self.members {
                busy |= m.turn(t, &mut self.inbox);
                due = due.min(m.core.next_idle_due(t));
            }
            if busy {
                continue;
            }
            let mut wake_at = now + Duration::from_secs_f64((due - t).clamp(0.0, 1.0));
            wake_at = wake_at.min(
                now + if rings {
                    MAX_SLEEP
                } else {
                    Duration::from_micros(200)
                },
            );
            if let Some(d) = stop.deadline {
                wake_at = wake_at.min(d);
            }
            bridge::wake::wait_until(wake_at);
        }
        self.members
            .iter()
            .map(|m| TwinCounts {
                received: m.received,
                stepped: m.stepped,
                errors: m.errors,
            })
            .collect()
    }
}

impl Member {
    /// One loop turn for this twin; `true` when a sample came.
    fn turn(&mut self, now: f64, inbox: &mut Vec<Message>) -> bool {
        inbox.clear();
        if let Err(e) = self.transport.poll(inbox) {
            tracing::warn!(error = %e, "fleet: poll for samples failed");
            self.errors += 1;
            self.core.count_transport_error();
        }
        let busy = !inbox.is_empty();
        for m in inbox.drain(..) {
            if let Message::Sample(s) = m {
                self.received += 1;
                let out = self.core.on_sample(&SensorSample::from_msg(&s), now);
                self.stepped += u64::from(out.output.is_some());
                for msg in out.into_messages() {
                    self.publish(&msg);
                }
            }
        }
        if let Some(d) = self.core.on_idle(now) {
            self.publish(&Message::Diagnostics(d));
        }
        busy
    }

    fn publish(&mut self, msg: &Message) {
        if let Err(e) = self.transport.publish(msg) {
            tracing::warn!(topic = msg.topic().ros_name(), error = %e, "fleet: publish failed");
            self.errors += 1;
            self.core.count_transport_error();
        }
    }
}

/// N stands played in step by one real-time paced loop: at each tick every stand's next
/// sample is published on its own transport.
pub struct FleetStands {
    players: Vec<(StandPlayer, Box<dyn Transport>)>,
    rate_hz: f64,
}

/// What one stand of the fleet did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StandCounts {
    /// Samples published.
    pub sent: u64,
    /// Publish errors, each logged.
    pub errors: u64,
}

impl FleetStands {
    /// One stand per `(parameters, transport)`; all must have the same `rate_hz`.
    pub fn new(stands: Vec<(StandParams, Box<dyn Transport>)>) -> Result<Self, NodeError> {
        let rate_hz = stands.first().map_or(1000.0, |(p, _)| p.rate_hz);
        let players = stands
            .into_iter()
            .map(|(p, t)| {
                if p.rate_hz != rate_hz {
                    return Err(NodeError::from(crate::config::InvalidParam {
                        key: "rate_hz",
                        reason: format!(
                            "every stand of a fleet plays at one rate ({rate_hz} Hz), {} has {}",
                            p.damper, p.rate_hz
                        ),
                    }));
                }
                Ok((StandPlayer::new(&p)?, t))
            })
            .collect::<Result<Vec<_>, NodeError>>()?;
        Ok(Self { players, rate_hz })
    }

    /// Play until `stop` or `duration`; per stand what it sent, and the loop's lateness.
    pub fn run(
        &mut self,
        stop: Option<&AtomicBool>,
        duration: Duration,
    ) -> (Vec<StandCounts>, StandSummary) {
        let epoch = crate::stand::wall_clock_s();
        for (player, _) in &mut self.players {
            player.set_epoch(epoch);
        }
        let mut summary = StandSummary::default();
        let mut counts = vec![StandCounts::default(); self.players.len()];
        let mut batch = Vec::new();
        let players = &mut self.players;
        run_paced(
            self.rate_hz,
            stop,
            Some(duration),
            &mut summary,
            |_, summary| -> Result<(), std::convert::Infallible> {
                for ((player, transport), c) in players.iter_mut().zip(&mut counts) {
                    player.next(&mut batch);
                    summary.generated += 1;
                    for s in &batch {
                        let msg = Message::Sample(s.to_msg(player.damper()));
                        if publish_sample(transport.as_mut(), player.damper(), &msg, summary) {
                            c.sent += 1;
                        } else {
                            c.errors += 1;
                        }
                    }
                }
                Ok(())
            },
        )
        .unwrap_or_else(|never| match never {});
        (counts, summary)
    }
}
