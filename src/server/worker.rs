//! A session's worker thread: takes messages off the session's bounded queue in order, drives
//! the engine, and broadcasts what it produces. The separation runs on a second thread of the
//! session (`execution.separation_thread`), at a lower priority, fed in order through a bounded
//! queue: the worker sends a step's tracks and goes on to the next message while that step's
//! audio is separated. A panic inside either is caught here: the session fails, its streams are
//! told and closed, and no other session notices.

use std::any::Any;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::Ordering;
use std::sync::mpsc::{Receiver, TrySendError, sync_channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::pipeline::{PipelineEvent, SeparationDriver, SeparationWork};
use crate::protocol::SessionEvent;
use crate::protocol::rest::{SessionState, TracksSnapshot};

use super::config::Execution;
use super::engine::Engine;
use super::session::{Input, Output, Queued, Rejection, Session, SessionHandle, Work};

/// Runs until the session's input is closed (then finishes the engine) or the engine panics.
pub(super) fn run<E: Engine>(
    mut engine: E,
    session: SessionHandle,
    rx: Receiver<Queued>,
    execution: &Execution,
) {
    let separation = if execution.separation_thread {
        start_separation(&mut engine, &session, execution)
    } else {
        None
    };
    // Dropping the engine closes the separation's queue; the thread then drains it and ends.
    let wind_up = |engine: E, separation: Option<JoinHandle<()>>| {
        drop(engine);
        if let Some(t) = separation {
            let _ = t.join();
        }
    };
    while let Ok(q) = rx.recv() {
        session.counters.queue_depth.fetch_sub(1, Ordering::AcqRel);
        session
            .counters
            .queue_bytes
            .fetch_sub(q.bytes, Ordering::AcqRel);
        if let Err(panic) = catch_unwind(AssertUnwindSafe(|| handle(&mut engine, &session, q))) {
            wind_up(engine, separation);
            session.close_failed(panic_message(panic.as_ref()));
            return;
        }
    }
    if session.state() == SessionState::Failed {
        // The separation failed and closed the input: nothing is left to finish.
        wind_up(engine, separation);
        return;
    }
    let started = Instant::now();
    let mut out = Publisher::new(&session, started);
    let finished = catch_unwind(AssertUnwindSafe(|| engine.finish(&mut |e| out.emit(e))));
    let busy = started.elapsed();
    if finished.is_ok() {
        session.counters.set_clutter(engine.clutter_rates());
    }
    wind_up(engine, separation);
    match finished {
        Ok(()) if session.state() != SessionState::Failed => {
            session.counters.processed(busy, 0, session.sample_rate());
            out.count_steps(busy);
            session.close_finished();
            tracing::info!(session = %session.id(), "session finished");
        }
        Ok(()) => {}
        Err(panic) => session.close_failed(panic_message(panic.as_ref())),
    }
}

/// Moves the engine's separation onto a thread of its own; None when the engine separates
/// nothing (or the thread cannot start, in which case the session fails).
fn start_separation<E: Engine>(
    engine: &mut E,
    session: &SessionHandle,
    execution: &Execution,
) -> Option<JoinHandle<()>> {
    let (tx, rx) = sync_channel::<SeparationWork>(execution.separation_queue);
    // A full queue blocks the worker (backpressure); a failed separation thread drops the work.
    // The count goes up before the send, so the thread never takes it below zero.
    let sender = session.clone();
    let driver = engine.detach_separation(Box::new(move |work| {
        let c = &sender.counters;
        c.separation_queued.fetch_add(1, Ordering::AcqRel);
        let sent = match tx.try_send(work) {
            Ok(()) => true,
            Err(TrySendError::Disconnected(_)) => false,
            Err(TrySendError::Full(work)) => {
                tracing::debug!(session = %sender.id(), "separation queue full: the pipeline waits for it");
                c.separation_waited();
                tx.send(work).is_ok()
            }
        };
        if !sent {
            c.separation_queued.fetch_sub(1, Ordering::AcqRel);
        }
    }))?;
    session
        .counters
        .separation_capacity
        .store(execution.separation_queue, Ordering::Relaxed);
    let for_thread = session.clone();
    let nice = execution.separation_nice;
    match std::thread::Builder::new()
        .name(format!("separate-{}", session.id()))
        .spawn(move || separate(driver, for_thread, rx, nice))
    {
        Ok(t) => Some(t),
        Err(e) => {
            session.close_failed(format!("cannot start the separation thread: {e}"));
            None
        }
    }
}

/// The separation thread: applies the work in order and broadcasts the audio.
fn separate(
    mut driver: SeparationDriver,
    session: SessionHandle,
    rx: Receiver<SeparationWork>,
    nice: i32,
) {
    lower_priority(nice);
    let mut out = Publisher::new(&session, Instant::now());
    while let Ok(work) = rx.recv() {
        session
            .counters
            .separation_queued
            .fetch_sub(1, Ordering::AcqRel);
        let started = thread_cpu_time();
        let applied = catch_unwind(AssertUnwindSafe(|| {
            driver.apply(work, &mut |e| out.emit(e));
        }));
        if let Err(panic) = applied {
            session.close_failed(format!("separation: {}", panic_message(panic.as_ref())));
            return;
        }
        // CPU time, not wall time: at low priority the wall clock also counts the waits for
        // other sessions' tracker steps.
        let busy = thread_cpu_time().saturating_sub(started);
        session.counters.processed(busy, 0, session.sample_rate());
    }
}

/// CPU time this thread has used.
fn thread_cpu_time() -> Duration {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec that we own.
    let ok = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) } == 0;
    if !ok {
        return Duration::ZERO;
    }
    Duration::new(
        ts.tv_sec.max(0) as u64,
        ts.tv_nsec.clamp(0, 999_999_999) as u32,
    )
}

/// Raises this thread's niceness by `nice` (never needs a privilege: it only lowers priority).
fn lower_priority(nice: i32) {
    if nice <= 0 {
        return;
    }
    // On Linux niceness belongs to a thread: PRIO_PROCESS with the thread's id sets this one only.
    #[cfg(target_os = "linux")]
    // SAFETY: plain system calls on this thread's own id, no memory passed.
    unsafe {
        let tid = libc::gettid() as libc::id_t;
        let now = libc::getpriority(libc::PRIO_PROCESS, tid);
        if libc::setpriority(libc::PRIO_PROCESS, tid, (now + nice).min(19)) != 0 {
            tracing::warn!("cannot lower the separation thread's priority");
        }
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
        ..
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
            if out.stepped() {
                s.counters.set_clutter(engine.clutter_rates());
            }
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
            // A live session's pipeline does not record pitch (offline diagnostics only).
            PipelineEvent::Pitch { .. } => return,
        };
        self.session.broadcast(out);
    }

    /// Whether the message ran at least one step.
    fn stepped(&self) -> bool {
        !self.latencies.is_empty()
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

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    fn own_nice() -> i32 {
        // SAFETY: a plain system call on this thread's own id.
        unsafe { libc::getpriority(libc::PRIO_PROCESS, libc::gettid() as libc::id_t) }
    }

    #[test]
    fn only_the_separation_thread_yields() {
        let mine = own_nice();
        let lowered = std::thread::spawn(|| {
            lower_priority(19);
            own_nice()
        })
        .join()
        .unwrap();
        assert_eq!(lowered, (mine + 19).min(19));
        assert_eq!(own_nice(), mine, "the calling thread keeps its priority");
    }

    #[test]
    fn thread_cpu_time_counts_work_not_sleep() {
        let t0 = thread_cpu_time();
        std::thread::sleep(Duration::from_millis(30));
        let slept = thread_cpu_time() - t0;
        let t1 = thread_cpu_time();
        let mut x = 0u64;
        while thread_cpu_time() - t1 < Duration::from_millis(5) {
            x = std::hint::black_box(x.wrapping_add(1));
        }
        assert!(
            slept < Duration::from_millis(10),
            "sleep counted: {slept:?}"
        );
        assert!(thread_cpu_time() - t1 >= Duration::from_millis(5));
    }
}
