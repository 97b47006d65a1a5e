//! A session's worker thread: takes messages off the session's bounded queue in order, drives
//! the engine, and broadcasts what it produces. A panic inside the engine is caught here: the
//! session fails, its streams are told and closed, and no other session notices.

use std::any::Any;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::Ordering;
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use crate::pipeline::PipelineEvent;
use crate::protocol::SessionEvent;
use crate::protocol::rest::TracksSnapshot;

use super::engine::Engine;
use super::session::{Input, Output, Queued, Rejection, Session, SessionHandle, Work};

/// Runs until the session's input is closed (then finishes the engine) or the engine panics.
pub(super) fn run<E: Engine>(mut engine: E, session: SessionHandle, rx: Receiver<Queued>) {
    while let Ok(q) = rx.recv() {
        session.counters.queue_depth.fetch_sub(1, Ordering::AcqRel);
        if let Err(panic) = catch_unwind(AssertUnwindSafe(|| handle(&mut engine, &session, q))) {
            session.close_failed(panic_message(panic.as_ref()));
            return;
        }
    }
    let started = Instant::now();
    let mut out = Publisher::new(&session, started);
    match catch_unwind(AssertUnwindSafe(|| engine.finish(&mut |e| out.emit(e)))) {
        Ok(()) => {
            let busy = started.elapsed();
            session.counters.processed(busy, 0, session.sample_rate());
            out.count_steps(busy);
            session.close_finished();
            tracing::info!(session = %session.id(), "session finished");
        }
        Err(panic) => session.close_failed(panic_message(panic.as_ref())),
    }
}

fn panic_message(panic: &(dyn Any + Send)) -> String {
    if let Some(s) = panic.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = panic.downcast_ref::<String>() {
        s.clone()
    } else {
        "panic".to_string()
    }
}

fn handle<E: Engine>(engine: &mut E, s: &Session, q: Queued) {
    let Queued {
        client,
        received,
        work,
    } = q;
    match work {
        Work::Input(input) => {
            let started = Instant::now();
            let mut out = Publisher::new(s, received);
            let mut sink = |e| out.emit(e);
            let (result, samples) = match input {
                Input::Audio(f) => (
                    engine.push_audio(f.first_sample, f.channels, &f.samples, &mut sink),
                    f.frames() as u64,
                ),
                Input::Detections(d) => (engine.push_detections(d, &mut sink), 0),
                Input::AudioMeasurements(m) => (engine.push_device_measurements(m, &mut sink), 0),
            };
            let busy = started.elapsed();
            s.counters.processed(busy, samples, s.sample_rate());
            out.count_steps(busy);
            if let Err(e) = result {
                s.counters.refused(e.code);
                s.broadcast(Output::Error {
                    to: Some(client),
                    error: Rejection::from(e).to_body(),
                });
            }
        }
        Work::Recalibrate(layout, reply) => {
            let result = engine.set_layout(layout.clone());
            if result.is_ok() {
                s.set_layout(layout);
                tracing::info!(session = %s.id(), "calibration replaced");
            }
            let _ = reply.send(result);
        }
        Work::Configure(settings, reply) => {
            let result = engine.update_config((*settings).clone());
            if result.is_ok() {
                s.set_settings(*settings);
                tracing::info!(session = %s.id(), "settings changed");
            }
            let _ = reply.send(result);
        }
    }
}

/// Broadcasts a message's events in order, each as soon as the engine produces it; a step's
/// latency runs from the arrival of the message that completed it to the broadcast of its tracks
/// (its separation runs after that).
struct Publisher<'a> {
    session: &'a Session,
    received: Instant,
    latencies: Vec<Duration>,
}

impl<'a> Publisher<'a> {
    fn new(session: &'a Session, received: Instant) -> Self {
        Self {
            session,
            received,
            latencies: Vec::new(),
        }
    }

    fn emit(&mut self, e: PipelineEvent) {
        // Audio and measurements nobody subscribed to are not broadcast at all.
        let interest = self.session.interest();
        match &e {
            PipelineEvent::Audio { .. } if !interest.audio() => return,
            PipelineEvent::Measurements(_) if !interest.measurements() => return,
            _ => {}
        }
        let out = match e {
            PipelineEvent::Tracks { step, line } => {
                let snap = TracksSnapshot {
                    step,
                    t: line.t,
                    tracks: line.tracks,
                };
                self.session.record_tracks(&snap);
                self.latencies.push(self.received.elapsed());
                Output::Tracks(snap)
            }
            PipelineEvent::Measurements(line) => Output::Measurements(line),
            PipelineEvent::Audio {
                label,
                first_sample,
                samples,
            } => Output::Audio {
                label,
                first_sample,
                samples,
            },
            PipelineEvent::TrackBorn { t, label } => {
                self.session
                    .counters
                    .labels_total
                    .fetch_add(1, Ordering::Relaxed);
                Output::Event(SessionEvent::TrackBorn { t, label })
            }
            PipelineEvent::TrackEnded { t, label } => {
                Output::Event(SessionEvent::TrackEnded { t, label })
            }
            PipelineEvent::Warning { code, message } => Output::Event(SessionEvent::Warning {
                code: code.to_string(),
                message,
            }),
        };
        self.session.broadcast(out);
    }

    /// Records the message's steps, each with its latency and an equal share of the message's
    /// processing time `busy`.
    fn count_steps(&self, busy: Duration) {
        let per_step = busy / self.latencies.len().max(1) as u32;
        for &latency in &self.latencies {
            self.session.counters.step(latency, per_step);
        }
    }
}
