//! Buffers of timestamped sensor frames (camera detections, device measurements) waiting for the
//! tracker step whose interval contains them.

use std::collections::VecDeque;
use std::mem::size_of;

use crate::geometry::Vec3;
use crate::scene::{AudioMeasurementFrame, DetectionFrame, Doa, FaceBox};

/// A sensor frame with a session time.
pub trait Timed {
    /// Session time (s).
    fn time(&self) -> f64;

    /// Bytes the frame holds while it waits: itself and its measurements.
    fn held_bytes(&self) -> usize;
}

impl Timed for DetectionFrame {
    fn time(&self) -> f64 {
        self.t
    }

    fn held_bytes(&self) -> usize {
        size_of::<Self>() + self.boxes.len() * size_of::<FaceBox>()
    }
}

impl Timed for AudioMeasurementFrame {
    fn time(&self) -> f64 {
        self.t
    }

    fn held_bytes(&self) -> usize {
        size_of::<Self>()
            + self.doas.len() * size_of::<Doa>()
            + self.points.len() * size_of::<Vec3>()
    }
}

/// The most bytes one waiting frame of at most `measurements` boxes, directions or points
/// holds (a camera's or a device's, whichever is larger).
pub fn largest_frame_bytes(measurements: usize) -> usize {
    let camera = size_of::<DetectionFrame>() + measurements * size_of::<FaceBox>();
    let per_device = size_of::<Doa>().max(size_of::<Vec3>());
    camera.max(size_of::<AudioMeasurementFrame>() + measurements * per_device)
}

/// Frames of one sensor in time order.
#[derive(Debug, Clone)]
pub struct SensorQueue<T> {
    frames: VecDeque<T>,
    last_t: f64,
    reported: bool,
    /// What the waiting frames hold ([`Timed::held_bytes`]).
    bytes: usize,
}

impl<T> Default for SensorQueue<T> {
    fn default() -> Self {
        Self {
            frames: VecDeque::new(),
            last_t: f64::NEG_INFINITY,
            reported: false,
            bytes: 0,
        }
    }
}

impl<T: Timed> SensorQueue<T> {
    /// Time of the newest frame received (-inf before the first).
    pub fn last_time(&self) -> f64 {
        self.last_t
    }

    /// Whether the sensor ever sent a frame.
    pub fn has_reported(&self) -> bool {
        self.reported
    }

    /// Number of frames waiting.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether no frame is waiting.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Bytes the waiting frames hold.
    pub fn held_bytes(&self) -> usize {
        self.bytes
    }

    /// Appends a frame whose time is not before the previous one (checked by the caller).
    pub fn push(&mut self, frame: T) {
        self.last_t = self.last_t.max(frame.time());
        self.reported = true;
        self.bytes += frame.held_bytes();
        self.frames.push_back(frame);
    }

    /// Removes and returns every frame with time before `t_end`.
    pub fn take_before(&mut self, t_end: f64) -> Vec<T> {
        let n = self.frames.iter().take_while(|f| f.time() < t_end).count();
        let taken: Vec<T> = self.frames.drain(..n).collect();
        let bytes: usize = taken.iter().map(Timed::held_bytes).sum();
        self.bytes = self.bytes.saturating_sub(bytes);
        taken
    }

    /// Forgets all waiting frames.
    pub fn clear(&mut self) {
        self.frames.clear();
        self.bytes = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(t: f64) -> DetectionFrame {
        DetectionFrame {
            t,
            camera: 0,
            boxes: vec![],
        }
    }

    #[test]
    fn hands_out_frames_by_step_end() {
        let mut q = SensorQueue::default();
        assert!(!q.has_reported());
        for t in [0.0, 0.1, 0.125, 0.25] {
            q.push(frame(t));
        }
        assert_eq!(q.take_before(0.125).len(), 2);
        assert_eq!(q.take_before(0.2).len(), 1);
        assert_eq!(q.last_time(), 0.25);
        assert_eq!(q.len(), 1);
    }

    #[test]
    fn counts_the_bytes_its_waiting_frames_hold() {
        let face = FaceBox {
            x: 1.0,
            y: 2.0,
            w: 3.0,
            h: 4.0,
            score: None,
            point: None,
        };
        let mut q = SensorQueue::default();
        let mut crowded = frame(0.1);
        crowded.boxes = vec![face; 10];
        let empty = frame(0.0).held_bytes();
        assert_eq!(crowded.held_bytes(), empty + 10 * size_of::<FaceBox>());
        assert!(crowded.held_bytes() <= largest_frame_bytes(10));
        q.push(frame(0.0));
        q.push(crowded.clone());
        assert_eq!(q.held_bytes(), empty + crowded.held_bytes());
        q.take_before(0.05);
        assert_eq!(q.held_bytes(), crowded.held_bytes());
        q.clear();
        assert_eq!(q.held_bytes(), 0);
    }
}
