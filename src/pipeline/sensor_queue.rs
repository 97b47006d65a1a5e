//! Buffers of timestamped sensor frames (camera detections, device measurements) waiting for the
//! tracker step whose interval contains them.

use std::collections::VecDeque;

use crate::scene::{AudioMeasurementFrame, DetectionFrame};

/// Something with a session time.
pub trait Timed {
    /// Session time (s).
    fn time(&self) -> f64;
}

impl Timed for DetectionFrame {
    fn time(&self) -> f64 {
        self.t
    }
}

impl Timed for AudioMeasurementFrame {
    fn time(&self) -> f64 {
        self.t
    }
}

/// Frames of one sensor in time order.
#[derive(Debug, Clone)]
pub struct SensorQueue<T> {
    frames: VecDeque<T>,
    last_t: f64,
    reported: bool,
}

impl<T> Default for SensorQueue<T> {
    fn default() -> Self {
        Self {
            frames: VecDeque::new(),
            last_t: f64::NEG_INFINITY,
            reported: false,
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

    /// Appends a frame whose time is not before the previous one (checked by the caller).
    pub fn push(&mut self, frame: T) {
        self.last_t = self.last_t.max(frame.time());
        self.reported = true;
        self.frames.push_back(frame);
    }

    /// Removes and returns every frame with time before `t_end`.
    pub fn take_before(&mut self, t_end: f64) -> Vec<T> {
        let n = self.frames.iter().take_while(|f| f.time() < t_end).count();
        self.frames.drain(..n).collect()
    }

    /// Forgets all waiting frames.
    pub fn clear(&mut self) {
        self.frames.clear();
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
}
