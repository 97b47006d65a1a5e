//! What REST reads of a session: its track history, latest estimate and detections, and the
//! info, summary and metrics documents.

use std::sync::atomic::Ordering;

use super::Session;
use crate::protocol::rest::{
    SessionInfo, SessionMetrics, SessionState, SessionSummary, TrackHistory, TracksSnapshot,
};
use crate::scene::DetectionFrame;
use crate::scene::convert::{array_to_file, camera_to_file, region_to_file};

impl Session {
    /// Track estimates from `from_step` on (all held when `None`), at most `limit`.
    pub fn history(&self, from_step: Option<u64>, limit: usize) -> TrackHistory {
        let Ok(h) = self.history.lock() else {
            return TrackHistory {
                oldest_step: None,
                steps: Vec::new(),
            };
        };
        let from = from_step.unwrap_or(0);
        TrackHistory {
            oldest_step: h.front().map(|s| s.step),
            steps: h
                .iter()
                .filter(|s| s.step >= from)
                .take(limit)
                .cloned()
                .collect(),
        }
    }

    /// The latest accepted frame of each camera, in camera order.
    pub fn latest_detections(&self) -> Vec<DetectionFrame> {
        self.latest_detections
            .lock()
            .map(|m| m.values().cloned().collect())
            .unwrap_or_default()
    }

    /// The latest track estimate.
    pub fn latest_tracks(&self) -> Option<TracksSnapshot> {
        self.history.lock().ok().and_then(|h| h.back().cloned())
    }

    /// The session's description with its current calibration.
    pub fn info(&self) -> SessionInfo {
        let layout = self.layout();
        let (state, error) = self
            .life
            .lock()
            .map_or((SessionState::Failed, None), |l| (l.state, l.error.clone()));
        SessionInfo {
            id: self.id.clone(),
            name: self.name.clone(),
            state,
            error,
            created_unix_s: self.created_unix_s,
            sample_rate: self.sample_rate,
            speed_of_sound: layout.speed_of_sound,
            channels: self.channels,
            arrays: layout.arrays.iter().map(array_to_file).collect(),
            cameras: layout.cameras.iter().map(camera_to_file).collect(),
            region: layout.region.as_ref().map(region_to_file),
            step_s: self.step_s,
            next_sample: self.next_sample(),
            clients: self.clients(),
            live_labels: self.live_labels(),
            memory_bound_bytes: self.memory_bound() as u64,
        }
    }

    /// Memory the session's pipeline and buffers may take at most
    /// ([`crate::server::budget::session_bound`]); none once it has ended.
    pub fn memory_bound(&self) -> usize {
        match self.state() {
            // The layout and settings in force were checked when they were applied, so they
            // have a bound.
            SessionState::Running | SessionState::Finishing => {
                crate::server::budget::session_bound(
                    &self.limits,
                    &self.execution,
                    &self.layout(),
                    &self.settings(),
                )
                .unwrap_or(0)
            }
            SessionState::Finished | SessionState::Failed => 0,
        }
    }

    /// The session's line in a listing.
    pub fn summary(&self) -> SessionSummary {
        SessionSummary {
            id: self.id.clone(),
            name: self.name.clone(),
            state: self.state(),
            created_unix_s: self.created_unix_s,
            clients: self.clients(),
            next_sample: self.next_sample(),
        }
    }

    /// The session's metrics.
    pub fn metrics(&self) -> SessionMetrics {
        let c = &self.counters;
        let (latency, processing) = c.latencies();
        let (audio_s, rtf) = c.real_time(self.sample_rate);
        SessionMetrics {
            state: self.state(),
            frames_in: c.frames_in(),
            refused: c.refusals(),
            output_dropped: c.dropped(),
            steps: c.steps(),
            step_latency_ms: latency,
            step_processing_ms: processing,
            real_time_factor: rtf,
            audio_s,
            live_tracks: c.live_tracks.load(Ordering::Relaxed),
            labels_total: c.labels_total.load(Ordering::Relaxed),
            queue_depth: c.queue_depth.load(Ordering::Relaxed),
            queue_capacity: self.limits.queue_depth,
            queue_bytes: c.queue_bytes.load(Ordering::Relaxed),
            queue_bytes_capacity: self.limits.queue_bytes,
            separation_queue_depth: c.separation_queued.load(Ordering::Relaxed),
            separation_queue_capacity: c.separation_capacity.load(Ordering::Relaxed),
            separation_waits: c.separation_waits(),
            clients: self.clients(),
            clutter: c.clutter(),
        }
    }
}
