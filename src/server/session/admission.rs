//! Admission of a client's input into the session: the checks that refuse it (measurement
//! counts, audio shape and order, a closed session) and the bounded queue it goes into.

use std::sync::atomic::Ordering;
use std::sync::mpsc::TrySendError;
use std::time::Instant;

use crate::pipeline::input::check_audio;
use crate::protocol::AudioFrame;
use crate::protocol::rest::SessionState;
use crate::scene::DetectionFrame;

use super::{ClientId, Inbox, Input, Queued, Rejection, Session, Work};

impl Session {
    /// The refusal of input once the session no longer takes any.
    pub(super) fn closed_rejection(&self) -> Rejection {
        match self.state() {
            SessionState::Failed => Rejection::new(
                "session_failed",
                "the session's pipeline failed; it accepts no more input",
            ),
            s => Rejection::new(
                "session_closed",
                format!("the session is {} and accepts no more input", s.as_str()),
            ),
        }
    }

    /// Queues input for the pipeline, or refuses it without blocking: too many measurements,
    /// invalid audio, audio out of order, a full queue (`queue_full`) or a closed session.
    /// Refusals are counted.
    pub fn submit(&self, client: ClientId, input: Input) -> Result<(), Rejection> {
        let kind = input.kind();
        let result = self.try_submit(client, input).map(|camera_frame| {
            if let Some(f) = camera_frame
                && let Ok(mut latest) = self.latest_detections.lock()
            {
                latest.insert(f.camera, f);
            }
        });
        match &result {
            Ok(()) => {
                self.counters.accepted(kind);
                self.last_use.touch(true);
            }
            Err(e) => self.counters.refused(e.code),
        }
        result
    }

    /// Checks and queues `input`; a queued camera frame comes back, copied only once every
    /// check has passed (a refused frame may be large).
    fn try_submit(
        &self,
        client: ClientId,
        input: Input,
    ) -> Result<Option<DetectionFrame>, Rejection> {
        let mut inbox = self
            .inbox
            .lock()
            .map_err(|_| Rejection::new("internal", "session lock poisoned"))?;
        if inbox.tx.is_none() {
            return Err(self.closed_rejection());
        }
        self.check_measurements(&input)?;
        let mut audio_end = None;
        if let Input::Audio(f) = &input {
            check_audio(&self.layout(), f.channels, &f.samples)?;
            audio_end = Some(self.check_audio_order(inbox.next_sample, f)?);
        }
        let camera_frame = match &input {
            Input::Detections(f) => Some(f.clone()),
            _ => None,
        };
        self.enqueue(&inbox, client, Work::Input(input))?;
        if let Some(end) = audio_end {
            inbox.next_sample = end;
        }
        Ok(camera_frame)
    }

    /// Refuses a camera or device frame with more measurements than
    /// `limits.max_measurements`, naming the list.
    fn check_measurements(&self, input: &Input) -> Result<(), Rejection> {
        let max = self.limits.max_measurements;
        // The longer list is the one that can pass the limit.
        let (field, n) = match input {
            Input::Audio(_) => return Ok(()),
            Input::Detections(d) => ("boxes", d.boxes.len()),
            Input::AudioMeasurements(m) if m.doas.len() >= m.points.len() => ("doas", m.doas.len()),
            Input::AudioMeasurements(m) => ("points", m.points.len()),
        };
        if n <= max {
            return Ok(());
        }
        Err(Rejection {
            code: "too_many_measurements",
            field: Some(field.to_string()),
            message: format!(
                "the frame carries {n} {field}, more than limits.max_measurements ({max})"
            ),
        })
    }

    /// Refuses audio that goes back in time or skips more than `max_gap_s`; returns the end of
    /// the frame.
    fn check_audio_order(&self, expected: u64, f: &AudioFrame) -> Result<u64, Rejection> {
        let first = f.first_sample;
        let field = Some("first_sample".to_string());
        if first < expected {
            return Err(Rejection {
                code: "time_backwards",
                field,
                message: format!(
                    "frame starts at sample {first} but sample {expected} is next (time goes backwards or overlaps)"
                ),
            });
        }
        let max_gap = self.max_gap_samples.load(Ordering::Relaxed);
        if first - expected > max_gap {
            return Err(Rejection {
                code: "gap_too_long",
                field,
                message: format!(
                    "frame starts at sample {first}, {} samples after the expected {expected}, more than max_gap_s allows",
                    first - expected
                ),
            });
        }
        Ok(first + f.frames() as u64)
    }

    /// Queues `work` for the worker within `limits.queue_bytes` and the queue's depth, or
    /// refuses it without blocking.
    pub(super) fn enqueue(
        &self,
        inbox: &Inbox,
        client: ClientId,
        work: Work,
    ) -> Result<(), Rejection> {
        let Some(tx) = inbox.tx.as_ref() else {
            return Err(self.closed_rejection());
        };
        let bytes = match &work {
            Work::Input(input) => input.bytes(),
            Work::Recalibrate(..) | Work::Configure(..) => 0,
        };
        // The inbox lock serialises senders and the worker only takes bytes out, so the sum
        // cannot pass the limit between this check and the send.
        let c = &self.counters;
        let held = c.queue_bytes.load(Ordering::Acquire);
        if held.saturating_add(bytes) > self.limits.queue_bytes {
            return Err(Rejection::new(
                "queue_full",
                format!(
                    "the session's queue holds {held} bytes of messages and this one takes \
                     {bytes}, more than limits.queue_bytes ({}) together; this one was \
                     dropped (send slower or retry)",
                    self.limits.queue_bytes
                ),
            ));
        }
        c.queue_depth.fetch_add(1, Ordering::AcqRel);
        c.queue_bytes.fetch_add(bytes, Ordering::AcqRel);
        let queued = Queued {
            client,
            received: Instant::now(),
            work,
            bytes,
        };
        match tx.try_send(queued) {
            Ok(()) => Ok(()),
            Err(e) => {
                c.queue_depth.fetch_sub(1, Ordering::AcqRel);
                c.queue_bytes.fetch_sub(bytes, Ordering::AcqRel);
                Err(match e {
                    TrySendError::Full(_) => Rejection::new(
                        "queue_full",
                        format!(
                            "the session's queue holds {} messages; this one was dropped (send slower or retry)",
                            self.limits.queue_depth
                        ),
                    ),
                    TrySendError::Disconnected(_) => self.closed_rejection(),
                })
            }
        }
    }
}
