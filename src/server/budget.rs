//! What one session may hold in memory at most, which the server's memory budget
//! (`limits.max_memory_mb`) admits sessions by: its pipeline ([`crate::pipeline::footprint`])
//! and the server's buffers around it (queued input, sensor frames waiting for their step,
//! queued separation work, outputs waiting for stream clients, the track history).

use std::mem::size_of;

use crate::geometry::Layout;
use crate::pipeline::{ConfigError, PipelineConfig, footprint};
use crate::protocol::rest::TracksSnapshot;
use crate::scene::format::TrackFile;
use crate::separate::Target;

use super::config::{Execution, Limits};
use super::session::Output;

/// Per output or snapshot, for what its size does not show (labels, codes, allocator slack).
const ITEM_ALLOWANCE: usize = 256;

/// Bytes a session with `layout` and `settings` may hold at most under `limits` and
/// `execution`: the pipeline's bound and [`buffers`]; an error naming the field for settings
/// no pipeline could be built with.
pub fn session_bound(
    limits: &Limits,
    execution: &Execution,
    layout: &Layout,
    settings: &PipelineConfig,
) -> Result<usize, ConfigError> {
    Ok(footprint(layout, settings)? + buffers(limits, execution, layout, settings))
}

/// Bytes the server's buffers around a session's pipeline may hold. Track snapshots are
/// counted at `separate.lifecycle.max_streams` tracks, the most labels the session separates.
pub fn buffers(
    limits: &Limits,
    execution: &Execution,
    layout: &Layout,
    settings: &PipelineConfig,
) -> usize {
    let channels = layout.channel_count();
    let rate = f64::from(layout.sample_rate);
    let step = (settings.step_s * rate).ceil() as usize;
    let frame = settings.separate.frame;
    let hop = settings.separate.hop;
    let tracks = settings.separate.lifecycle.max_streams;
    let snapshot = size_of::<TracksSnapshot>() + tracks * size_of::<TrackFile>() + ITEM_ALLOWANCE;
    // Each output sits behind an `Arc` in the broadcast ring: separated audio one hop of one
    // label, or a snapshot; measurements lines are smaller than either.
    let output = 16 + size_of::<Output>() + snapshot.max(4 * hop + ITEM_ALLOWANCE);
    // A step of separation work: its audio (the last one also carries a frame of padding) and
    // each frame's targets. Beside the queue's steps, one is in the separation thread's hands
    // and one in the worker's, which waits to send it while the queue is full.
    let separation = if settings.separation && execution.separation_thread {
        let samples = step + frame;
        let frames = samples / hop.max(1) + 1;
        (execution.separation_queue + 2)
            * (channels * samples * size_of::<f32>()
                + frames * (24 + tracks * size_of::<Target>())
                + ITEM_ALLOWANCE)
    } else {
        0
    };
    limits.queue_bytes
        + limits.sensor_backlog_bytes
        + separation
        + limits.output_buffer * output
        + limits.history_steps * snapshot
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::server::ServerConfig;

    fn uca8() -> Layout {
        let opts = crate::scene::sim::PresetOptions::default();
        let cfg = crate::scene::sim::SimConfig::preset("uca8", &opts, 1).unwrap();
        crate::scene::sim::layout::build(&cfg).unwrap()
    }

    /// The buffers of an 8-microphone session.
    fn parts(limits: &Limits, execution: &Execution, settings: &PipelineConfig) -> usize {
        buffers(limits, execution, &uca8(), settings)
    }

    #[test]
    fn the_buffers_count_the_input_queue_whole_and_the_separation_queue_when_it_runs() {
        let c = ServerConfig::default();
        let s = PipelineConfig::default();
        let base = parts(&c.limits, &c.execution, &s);
        let mut wider = c.limits.clone();
        wider.queue_bytes += 1 << 20;
        assert_eq!(parts(&wider, &c.execution, &s), base + (1 << 20));
        wider.sensor_backlog_bytes += 1 << 20;
        assert_eq!(parts(&wider, &c.execution, &s), base + (2 << 20));
        let inline = Execution {
            separation_thread: false,
            ..c.execution.clone()
        };
        let no_separation = PipelineConfig {
            separation: false,
            ..s.clone()
        };
        let without = parts(&c.limits, &inline, &s);
        assert_eq!(parts(&c.limits, &c.execution, &no_separation), without);
        // 16 steps of 8 channels' audio (2,048 samples and a 1,024-sample frame): 1.6 MB.
        assert!(base - without > 16 * 8 * 3072 * 4, "{}", base - without);
    }

    /// A full history of snapshots with as many tracks as the stream cap, and a full ring of
    /// separated audio hops, each take no more than the bound counts for them.
    #[test]
    fn full_histories_and_rings_fit_their_share() {
        let c = ServerConfig::default();
        let s = PipelineConfig::default();
        let inline = Execution {
            separation_thread: false,
            ..c.execution.clone()
        };
        let track = TrackFile {
            label: crate::label::Label::new(1, 0),
            position: [1.0; 3],
            velocity: [0.0; 3],
            existence: 1.0,
            speaking: 0.5,
            covariance: Some([[0.1; 3]; 3]),
        };
        let tracks: Vec<TrackFile> = vec![track; s.separate.lifecycle.max_streams];
        let snapshot = size_of::<TracksSnapshot>() + tracks.capacity() * size_of::<TrackFile>();
        let samples: Vec<f32> = vec![0.0; s.separate.hop];
        let audio = 16 + size_of::<Output>() + samples.capacity() * 4;
        let held = c.limits.history_steps * snapshot
            + c.limits.output_buffer * (16 + size_of::<Output>() + snapshot).max(audio);
        let counted =
            parts(&c.limits, &inline, &s) - c.limits.queue_bytes - c.limits.sensor_backlog_bytes;
        assert!(held <= counted, "{held} > {counted}");
        assert!(counted < held + (1 << 20), "{counted} against {held}");
    }
}
